"""``glshade measure``: how visible a scene's defect is, by the paper's stripe metric or
a phase-measuring station (``--method``; :func:`run` chooses between the two)."""

from __future__ import annotations

import argparse
import time

from glshade.app.args import (
    add_metric_flags,
    add_pmd_settings_flags,
    add_scene_flags,
    check_outputs,
    check_save_scene,
    metric_flags_given,
    metric_settings,
    path_arg,
    pmd_flags_given,
    pmd_settings,
    run_inputs,
    save_scene,
    scene_from_args,
    warn,
)
from glshade.errors import GlshadeError
from glshade.measure.pmd_files import FRAME_FORMATS
from glshade.measure.single import as_method, method_for, methods
from glshade.metrics.status import concerns, contrast_warning
from glshade.oracle.advice import scene_warnings
from glshade.process import reuse_freed_memory
from glshade.scene import Scene


def add(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "measure",
        help="how visible is a scene's defect (the three numbers of docs/study.md)",
        description="Render a scene with and without its defect and measure the defect's "
        "visibility: the "
        "paper's metric (visibility_px), its continuous limit (visibility_continuous_px), how far "
        "the rays move "
        "(deflection_px), whether the stripe map folds, its islands and the best phase, beside "
        "the closed forms "
        "(docs/physics.md). Scene and flags as for render.",
    )
    add_scene_flags(p)
    add_metric_flags(p)
    p.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    p.add_argument(
        "--overlay",
        type=path_arg,
        metavar="PNG",
        help="also write the Fig. 9 contour overlay at the best phase",
    )
    add_pmd_flags(p)


def add_pmd_flags(p: argparse.ArgumentParser) -> None:
    """The instrument (--method) and phase measuring's own flags (docs/pmd.md)."""
    p.add_argument(
        "--method",
        choices=methods(),
        help="the instrument: paper (binarised stripe edges) or pmd (phase-measuring "
        "deflectometry: the fringe sequence decoded); default: pmd where the emitter shows "
        "fringes, else paper. pmd on a scene of stripes shows the fringes on the same screen",
    )
    p.add_argument(
        "--maps",
        type=path_arg,
        metavar="DIR",
        help="pmd: write the maps behind the numbers (decoded.npy, exact.npy, modulation.npy, "
        "modulation_share.npy, wrapped_phase.npy, error_mm.npy, slopes.npy, height_um.npy, "
        "the defect-free and noise-twin decodes, ...; docs/pmd.md) and figures",
    )
    p.add_argument(
        "--frames",
        type=path_arg,
        metavar="DIR",
        help="pmd: write the recorded sequence, the recorded white and manifest.json (all an "
        "external decoder needs); an earlier run's frames there are replaced",
    )
    p.add_argument(
        "--frame-format",
        choices=tuple(FRAME_FORMATS),
        default="png",
        help="pmd --frames: 16-bit PNG (default) or 32-bit float TIFF",
    )
    add_pmd_settings_flags(p)


def run(args: argparse.Namespace) -> int:
    import json

    from glshade.gpu.context import GLContext
    from glshade.gpu.renderer import Renderer
    from glshade.instruments.record import Measurement
    from glshade.instruments.stripes.single import measure_scene

    scene = scene_from_args(args)
    method = method_for(scene, args.method)
    if method == "pmd":
        return _run_pmd(args, as_method(scene, "pmd"))
    given = [
        flag
        for flag, value in (("--maps", args.maps), ("--frames", args.frames))
        if value is not None
    ] + pmd_flags_given(args)
    if given:
        raise GlshadeError(f"{given[0]}: belongs to --method pmd (phase measuring)")
    settings = metric_settings(args)
    # a step longer than the period is refused before rendering
    settings.phases(scene.active.emitter.pattern(scene).period_mm)
    overlay = [("--overlay", args.overlay, (".png",))] if args.overlay is not None else []
    check_outputs(args, scene, overlay)
    warn(scene_warnings(scene))
    reuse_freed_memory()  # the phases' temporaries: about 40 ms of page faults otherwise
    start = time.perf_counter()
    with (
        GLContext(device_index=args.device) as context,
        Renderer(context, progress=True) as renderer,
    ):
        result = measure_scene(renderer, scene, settings, overlay=args.overlay)
    seconds = time.perf_counter() - start
    record = Measurement.of(scene, result)
    save_scene(args, scene)
    low = contrast_warning(result.stripe_contrast, scene.active.dimming(scene))
    warn([low] if low else [])
    if args.json:
        size = [scene.camera.width, scene.camera.height]
        out = {
            **record.outputs(),
            "scene": scene.title(),
            "size": size,
            "seconds": round(seconds, 3),
        }
        print(json.dumps(out))
        return 0
    _print_measurement(scene, record)
    if args.overlay is not None:
        print(f"  wrote {args.overlay}")
    return 0


def _run_pmd(args: argparse.Namespace, scene: Scene) -> int:
    """``glshade measure --method pmd``: what a PMD station measures of the scene's dent."""
    import json

    from glshade.gpu.context import GLContext
    from glshade.gpu.renderer import Renderer
    from glshade.instruments.record import PmdMeasurement
    from glshade.measure.pmd import check_scene, measure_pmd_scene
    from glshade.measure.pmd_files import check_output_dir, write_frames, write_maps

    for flag in metric_flags_given(args) + (["--overlay"] if args.overlay is not None else []):
        raise GlshadeError(f"{flag}: belongs to the paper's stripe metric, not to --method pmd")
    settings = pmd_settings(args)
    check_scene(scene)
    for flag, directory in (("--maps", args.maps), ("--frames", args.frames)):
        if directory is not None:
            check_output_dir(directory, flag, run_inputs(args, scene))
    check_save_scene(args, scene)
    warn(scene_warnings(scene))
    reuse_freed_memory()
    start = time.perf_counter()
    with (
        GLContext(device_index=args.device) as context,
        Renderer(context, progress=True) as renderer,
    ):
        result = measure_pmd_scene(renderer, scene, settings)
    seconds = time.perf_counter() - start
    record = PmdMeasurement.of(scene, result)
    if args.frames is not None:
        write_frames(args.frames, scene, result, args.frame_format)
    if args.maps is not None:
        write_maps(args.maps, scene, result)
    save_scene(args, scene)
    if args.json:
        size = [scene.camera.width, scene.camera.height]
        out = {**record.outputs(), "scene": scene.title(), "size": size}
        print(json.dumps({**out, "seconds": round(seconds, 3)}))
        return 0
    _print_pmd(scene, record)
    for flag, directory in (("--frames", args.frames), ("--maps", args.maps)):
        if directory is not None:
            print(f"  wrote {directory}/ ({flag})")
    return 0


def _print_pmd(scene: Scene, record) -> None:
    """A PMD record as a small table; a number its status makes unreadable says so on
    its own line."""
    from glshade.components.emitter.fringes.table import fringes_of
    from glshade.measure.pmd import pmd_concerns

    em, cam = fringes_of(scene), scene.camera
    frames = len(em.directions) * len(em.periods) * em.shifts
    print(
        f"{scene.title()} ({cam.width}x{cam.height}, phase measuring: {frames} frames, "
        f"{len(em.directions)} directions x {len(em.periods)} periods x {em.shifts} shifts, "
        f"finest {em.periods[0]:g} mm)"
    )
    reason = "" if record.status == "ok" else f": {record.status_reason}"
    print(f"  status                  {record.status}{reason}")

    def flag(column: str) -> str:
        return f"  [{record.status}: not measurable]" if pmd_concerns(record.status, column) else ""

    def number(value, fmt: str) -> str:
        return "n/a" if value is None else format(value, fmt)

    snr = "inf (no sensor: noise-free)" if record.pmd_snr is None else f"{record.pmd_snr:.1f}"
    law_caveat = (
        ""
        if record.pmd_shift_law_status == "ok"
        else f" [{record.pmd_shift_law_status}: {record.pmd_shift_law_reason}]"
    )
    dmax_um, sigma_mm = 1e3 * scene.defect.dmax, scene.defect.sigma_z2**0.5
    rows = [
        ("pmd_shift_mm", f"{number(record.pmd_shift_mm, '.4f')} mm on the screen (closed form "
         f"{number(record.pmd_shift_law_mm, '.4f')}{law_caveat})"),
        ("pmd_noise_mm", f"{number(record.pmd_noise_mm, '.2e')} mm (predicted "
         f"{number(record.pmd_noise_predicted_mm, '.2e')}; noise alone shifts up to "
         f"{number(record.pmd_noise_floor_mm, '.2e')})"),
        ("pmd_snr", snr),
        ("pmd_slope_urad", f"{number(record.pmd_slope_urad, '.1f')} µrad (largest in the dent)"),
        ("pmd_depth_um", f"{number(record.pmd_depth_um, '.3f')} µm reconstructed (true "
         f"{dmax_um:g} µm)"),
        ("pmd_sigma_mm", f"{number(record.pmd_sigma_mm, '.3f')} mm (true {sigma_mm:.3g})"),
        ("decode_rms_mm", f"{number(record.decode_rms_mm, '.2e')} mm (decoded - exact, "
         "defect-free)"),
        ("unwrap_failures", f"{record.unwrap_failures} pixels"),
        ("valid_fraction", f"{record.valid_fraction:.4f} of the pixels that see the screen"),
        ("modulation", f"{number(record.modulation, '.3f')} of a sharp mirror's (the finest "
         "fringe's share, at the dent, else where the screen is seen)"),
    ]  # fmt: skip
    for name, text in rows:
        print(f"  {name:<22}  {text}{flag(name)}")


def _print_measurement(scene: Scene, record) -> None:
    """The record as a small table, each number with what it means; a number that cannot
    be read says so on its own line (its status, and why)."""
    cam = scene.camera
    print(
        f"{scene.title()} ({cam.width}x{cam.height}, {scene.render.precision}, "
        f"{scene.render.reflection})"
    )
    ok = record.status == "ok"
    print(
        f"  status                    {record.status}" + ("" if ok else f": {record.status_reason}")
    )

    def flag(column: str) -> str:
        return f"  [{record.status}: not measurable]" if concerns(record.status, column) else ""

    print(
        f"  visibility_px             {record.visibility_px:g}  (the paper's metric, best phase "
        f"{record.best_phase_mm:g} mm){flag('visibility_px')}"
    )
    print(
        f"  visibility_continuous_px  {record.visibility_continuous_px:.2f}  (its limit: finer "
        f"phase step and pixels){flag('visibility_continuous_px')}"
    )
    print(
        f"  deflection_px             {record.deflection_px:.2f}  (how far the rays move)"
        f"{flag('deflection_px')}"
    )
    fold = f"yes, {record.islands} islands at most" if record.folded else "no"
    print(f"  folded                    {fold}")
    print(
        f"  stripe_contrast           {_number(record.stripe_contrast)}  (of the emitter's; 1: "
        "a sharp mirror)"
    )
    if record.noise_floor_px is not None:
        print(
            f"  noise_floor_px            {record.noise_floor_px:g}  (the metric between two noisy "
            "exposures of the defect-free scene)"
        )
    laws = [
        f"deflection {_number(record.deflection_law_px)} px",
        f"visible {_number(record.visibility_law_px)} px",
        f"fold ratio {_number(record.fold_ratio)} (folds above 1)",
    ]
    print(f"  closed forms              {', '.join(laws)}")


def _number(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.2f}"
