"""``glshade`` command line: a thin layer over the library.

Bad input (a malformed file or value, an unknown key, a missing system library or
display, an output path that cannot be written or is not a regular file) prints one
line, ``glshade: error: …``, and exits with code 2. Every output path is checked before
any work starts, and files are written atomically, so nothing is written half-way.
Values that are accepted but implausible print ``glshade: warning: …`` lines. The scene
format, its units and ranges: ``docs/scene-format.md``.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import gc
import sys
import time
from collections.abc import Callable
from pathlib import Path

from glshade import __version__
from glshade.app.args import (
    EXIT_USAGE,
    SIZE_HELP,
    Parser,
    add_metric_flags,
    add_pmd_settings_flags,
    add_save_scene,
    add_scene_flags,
    check_memory,
    check_outputs,
    check_save_scene,
    metric_flags_given,
    metric_settings,
    one_line,
    path_arg,
    pmd_flags_given,
    pmd_settings,
    quantity_list,
    run_inputs,
    save_scene,
    scene_from_args,
    warn,
)
from glshade.app.interrupts import InterruptWatch
from glshade.errors import GlshadeError, GlshadeWarning, ShaderCompileError
from glshade.files import atomic_write_bytes, reading_inputs
from glshade.measure.pmd_files import FRAME_FORMATS
from glshade.measure.single import METHODS, as_method, method_for
from glshade.metrics.status import concerns, contrast_warning
from glshade.oracle.advice import scene_warnings
from glshade.process import reuse_freed_memory
from glshade.scene import Camera, Scene, paper_scene

EXIT_INTERRUPTED = 130
#: The exit code of an error that is glshade's defect, not the user's.
EXIT_DEFECT = 1
SCENE_FORMAT = "docs/scene-format.md"


def _add_render(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "render",
        help="render one image (and its uv map)",
        description=f"Render a scene: a TOML scene file ({SCENE_FORMAT}: every key, unit, default "
        "and range) "
        "or, without one, the paper's scene (flat, theta 45, sigma2 4 mm², dmax 5 µm, 1024²). "
        "Flags override "
        "the file; lengths are in mm unless they carry a unit (--dmax 5um).",
    )
    add_scene_flags(p)
    p.add_argument(
        "-o",
        "--output",
        type=path_arg,
        default=Path("render.png"),
        help="image, PNG or TIFF by its extension (default render.png); lossy formats are refused",
    )
    p.add_argument(
        "--bits",
        type=int,
        choices=(8, 16, 32),
        default=8,
        help="bits per pixel: 8 or 16 (integers), 32 (float radiance, TIFF only); default 8",
    )
    p.add_argument(
        "--uv",
        type=path_arg,
        metavar="UV.npy",
        help="also write the uv map (float32 H×W×2, mm, NaN = no hit)",
    )
    p.set_defaults(run=_cmd_render)


def _add_measure(sub: argparse._SubParsersAction) -> None:
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
    p.set_defaults(run=_cmd_measure)


def add_pmd_flags(p: argparse.ArgumentParser) -> None:
    """The instrument (--method) and phase measuring's own flags (docs/pmd.md)."""
    p.add_argument(
        "--method",
        choices=METHODS,
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


def _cmd_measure(args: argparse.Namespace) -> int:
    import json

    from glshade.gpu.context import GLContext
    from glshade.gpu.renderer import Renderer
    from glshade.measure.record import Measurement
    from glshade.measure.single import measure_scene

    scene = scene_from_args(args)
    method = method_for(scene, args.method)
    if method == "pmd":
        return _cmd_measure_pmd(args, as_method(scene, "pmd"))
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


def _cmd_measure_pmd(args: argparse.Namespace, scene: Scene) -> int:
    """``glshade measure --method pmd``: what a PMD station measures of the scene's dent."""
    import json

    from glshade.gpu.context import GLContext
    from glshade.gpu.renderer import Renderer
    from glshade.measure.pmd import check_scene, measure_pmd_scene
    from glshade.measure.pmd_files import check_output_dir, write_frames, write_maps
    from glshade.measure.record import PmdMeasurement

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


def _add_info(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("info", help="print the GL renderer, version and fp64 support")
    p.add_argument(
        "--device", type=int, metavar="N", help="EGL device index (default GLSHADE_EGL_DEVICE or 0)"
    )
    p.set_defaults(run=_cmd_info)


#: ``glshade paper --help``'s description.
_PAPER_DESCRIPTION = (
    "Run Table 1 of the paper (9 theta x 4 sigma2 x 2 dmax on flat, cylinder and sphere) and "
    "write results.csv, image grids, visibility plots, the Fig. 9 contour overlay and "
    "report.md. Rerunning with the same --out resumes: finished cases are skipped. The "
    "directory is locked while a run uses it; one that holds a study with another plan is "
    "refused unless --overwrite. --method pmd measures the same cases with a phase-measuring "
    "station and writes pmd_results.csv, pmd_report.md and pmd_*.png beside the stripe study "
    "(docs/study.md)."
)


def _add_paper(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "paper",
        help="run the paper's whole study (the main job)",
        description=_PAPER_DESCRIPTION,
    )
    _add_paper_output_flags(p)
    _add_paper_plan_flags(p)
    add_metric_flags(p)
    _add_paper_run_flags(p)
    from glshade.app.cli_paper_pmd import add_pmd_paper_flags

    add_pmd_paper_flags(p)
    p.set_defaults(run=_cmd_paper)


def _add_paper_output_flags(p: argparse.ArgumentParser) -> None:
    """``glshade paper``'s output directory: ``--overwrite`` and ``--out``."""
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace a study with another plan in --out (its results, figures and report are "
        "removed)",
    )
    p.add_argument(
        "--out",
        type=path_arg,
        default=Path("paper_study"),
        metavar="DIR",
        help="output directory (default paper_study)",
    )


def _add_paper_plan_flags(p: argparse.ArgumentParser) -> None:
    """``glshade paper``'s plan: the surfaces, the axes of Table 1 and the image size."""
    p.add_argument(
        "--surfaces",
        default="flat,cylinder,sphere",
        metavar="LIST",
        help="comma-separated surface kinds, or scene files (.toml) of free-form surfaces",
    )
    p.add_argument(
        "--thetas",
        type=quantity_list("camera.theta_deg"),
        metavar="LIST",
        help="camera elevations, degrees, strictly decreasing (default 85,75,…,5)",
    )
    p.add_argument(
        "--sigma2s",
        type=quantity_list("defect.sigma2"),
        metavar="LIST",
        help="defect variances, mm² or with a unit (default 1,4,9,16)",
    )
    p.add_argument(
        "--dmaxs",
        type=quantity_list("defect.dmax"),
        metavar="LIST",
        help="defect depths, mm or with a unit: 0.003,0.005 or 3um,5um (the default)",
    )
    p.add_argument(
        "--size",
        type=int,
        default=1024,
        metavar="N",
        help="pixels across, the paper's field of view (default 1024)",
    )


def _add_paper_run_flags(p: argparse.ArgumentParser) -> None:
    """How ``glshade paper`` runs: workers, threads, the size confirmation, the progress
    bar and the EGL device."""
    p.add_argument(
        "--workers",
        default="auto",
        metavar="N",
        help="worker processes, each tracing and measuring whole geometries with its own "
        "renderer (a local Dask cluster); 0: in this process; auto (the default): 2 when "
        "the study is large enough to repay their start (64 cases at 512² or the like), "
        "else 0",
    )
    p.add_argument(
        "--threads",
        type=int,
        default=2,
        metavar="N",
        help="in this process: threads for the metric's analysis while this thread traces "
        "(default 2)",
    )
    p.add_argument(
        "--yes",
        action="store_true",
        help="run a study of more cases (surfaces x thetas x sigma2s x dmaxs) than the "
        "confirmation limit",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument(
        "--device", type=int, metavar="N", help="EGL device index (in this process only)"
    )


def _cmd_paper(args: argparse.Namespace) -> int:
    from glshade.app.cli_paper_pmd import check_method_flags, cmd_paper_pmd, pmd_plan
    from glshade.measure.locks import run_lock
    from glshade.study import plan as study
    from glshade.study.run import check_workers

    check_workers(args.threads)  # before --out is touched
    check_method_flags(args)
    metric = metric_settings(args)
    surfaces = tuple(part.strip() for part in args.surfaces.split(",") if part.strip())
    plan = study.StudyPlan(
        surfaces=surfaces,
        thetas=tuple(args.thetas) if args.thetas is not None else study.PAPER_THETAS,
        sigma2s=tuple(args.sigma2s) if args.sigma2s is not None else study.PAPER_SIGMA2S,
        dmaxs=tuple(args.dmaxs) if args.dmaxs is not None else study.PAPER_DMAXS,
        size=args.size,
        metric=metric,
    )
    study.check_size(plan, args.yes)  # before --out is touched, in both methods
    args.workers = paper_workers(args.workers, plan, args.device)
    if args.method == "pmd":
        pmd = pmd_plan(args, plan)  # bad input is refused before --out is touched
        with run_lock(args.out):
            return cmd_paper_pmd(args, plan, pmd, _run_paper)
    from glshade.measure.engine import Case

    firsts = [(surface, *plan.cases()[0][1:]) for surface in plan.surfaces]
    check_memory(
        [Case(point, plan.scene(*point)) for point in firsts],
        plan.metric,
        threads=args.threads,
        pooled=not args.workers,
    )
    warn(
        tuple(
            line
            for sigma2 in plan.sigma2s
            for dmax in plan.dmaxs
            for line in scene_warnings(plan.scene(plan.surfaces[0], plan.thetas[0], sigma2, dmax))
        )
    )
    with run_lock(args.out):
        return _run_paper(args, plan)


#: ``--workers auto`` starts worker processes for a study of at least this many pixels to
#: trace and measure (64 cases at 512²): below it their start-up (about 2 s) is not repaid.
AUTO_WORKERS_PIXELS = 64 * 512 * 512


def paper_workers(given: str, plan, device: int | None) -> int:
    """The worker processes of a study: ``--workers`` (an integer >= 0, or ``auto``), at
    most as many as this machine's cores and memory budget hold at the plan's size
    (:mod:`glshade.measure.capacity`; ``auto`` takes at most that many)."""
    from glshade.measure.capacity import check_worker_count, worker_limit

    pixels = plan.size * plan.size
    if given == "auto":
        large = len(plan.cases()) * pixels >= AUTO_WORKERS_PIXELS
        fits = worker_limit(pixels, "paper").allowed
        return min(2, fits) if large and device is None and fits > 1 else 0
    try:
        workers = int(given)
    except ValueError:
        workers = -1
    if not 0 <= workers <= 256:
        raise GlshadeError(f"--workers: must be auto or an integer in [0, 256], got {given}")
    if workers:
        check_worker_count(workers, pixels, "paper", in_process=True)
    if workers and device is not None:
        raise GlshadeError(
            "--device: only with --workers 0 (worker processes take the EGL device of their "
            "CUDA_VISIBLE_DEVICES)"
        )
    return workers


def _run_paper(args: argparse.Namespace, plan) -> int:
    """The study, its figures and its report, with ``--out`` locked."""
    from glshade.gpu.context import GLContext
    from glshade.gpu.renderer import Renderer
    from glshade.study import findings, plots
    from glshade.study import plan as study
    from glshade.study.run import run_study
    from glshade.study.store import CaseResult

    reuse_freed_memory()
    start = time.perf_counter()
    drawn: dict = {}
    figure_seconds = 0.0

    def draw(
        surface: str, rows: list[CaseResult]
    ) -> None:  # while the workers measure the next surface
        nonlocal figure_seconds
        begin = time.perf_counter()
        drawn[surface] = plots.surface_figures(rows, args.out, plan, surface)
        figure_seconds += time.perf_counter() - begin

    run = functools.partial(
        run_study,
        plan,
        args.out,
        progress=not args.no_progress,
        on_surface_done=draw,
        overwrite=args.overwrite,
    )
    if args.workers:
        from glshade.measure.executors import Distribution

        result = run(distribution=Distribution(workers=args.workers, verbose=args.verbose))
    else:
        with GLContext(device_index=args.device) as context, Renderer(context) as renderer:
            result = run(workers=args.threads, renderer=renderer)
    figure_start = time.perf_counter()
    written = plots.write_figures(result.rows, args.out, plan, drawn)
    result.timings.figures = figure_seconds + time.perf_counter() - figure_start
    overlays = [
        args.out / name for name in study.OVERLAY_CASES.values() if (args.out / name).exists()
    ]
    report = findings.write_report(result.rows, args.out, plan, overlays + written, result.timings)
    print(
        f"{result.computed} cases computed, {result.skipped} resumed; wrote "
        f"{args.out / 'results.csv'}, "
        f"{len(written)} figures and {report} in {time.perf_counter() - start:.1f} s"
    )
    return 0


#: The viewer's pixels across without ``--size``.
VIEW_SIZE = 512


def _add_view(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "view",
        help="open the interactive viewer (needs the viewer extra)",
        description="Open a window that renders the scene with the batch renderer's shaders, with "
        "a control "
        "panel, views (image, defect-free, contour overlay, displacement, and the maps of a "
        "phase-measuring station: pmd-phase, pmd-modulation, pmd-error, pmd-slope) and live "
        "readouts. "
        "Keys: S screenshot, T save the scene as TOML, R reset to the paper's defaults, O toggle "
        "the overlay, P toggle the PMD phase view. "
        "Scripted mode: --frames N [--screenshot out.png] [--set theta=5 ...].",
    )
    p.add_argument(
        "scene", nargs="?", type=path_arg, help="scene file (TOML); default: the paper's scene"
    )
    p.add_argument(
        "--size",
        type=int,
        metavar="N",
        help=f"{SIZE_HELP} (default {VIEW_SIZE}, unless --set camera.width is given)",
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a setting by its short name or dotted path, as render's --set: theta=5, "
        "sigma2=9, surface=sphere, camera.distance=200; and the viewer's own: view=overlay, "
        "animate=1, view=pmd-phase, pmd_size=256 (the PMD views' pixels across), concave=1 "
        "(repeatable)",
    )
    p.add_argument("--frames", type=int, metavar="N", help="draw N frames, then exit")
    p.add_argument(
        "--screenshot", type=path_arg, metavar="PNG", help="with --frames: save the last frame"
    )
    p.add_argument(
        "--benchmark",
        choices=("phase", "theta"),
        help="with --frames: animate the phase or drag theta, print fps",
    )
    p.add_argument(
        "--no-panel", action="store_true", help="no control panel (the window shows the image only)"
    )
    add_save_scene(p)
    p.set_defaults(run=_cmd_view)


def _cmd_view(args: argparse.Namespace) -> int:
    from glshade.app import viewer

    scene = Scene.load(args.scene) if args.scene is not None else paper_scene()
    scene, extra = viewer.parse_sets(args.set, scene, args.size, default_size=VIEW_SIZE)
    if args.frames is not None and args.frames < 1:
        raise GlshadeError(f"--frames: must be an integer >= 1, got {args.frames}")
    if (args.screenshot is not None or args.benchmark) and args.frames is None:
        raise GlshadeError("--screenshot and --benchmark need --frames N")
    screenshot = [("--screenshot", args.screenshot, (".png",))] if args.screenshot else []
    check_outputs(args, scene, screenshot)
    warn(scene_warnings(scene))
    save_scene(args, scene)  # the scene the window opens with (T saves it as it is then)
    options = viewer.ViewerOptions(
        scene=scene,
        view=extra.get("view", "image"),
        animate=args.benchmark == "phase"
        or extra.get("animate", "0").lower() in ("1", "true", "yes"),
        frames=args.frames,
        screenshot=args.screenshot,
        benchmark=args.benchmark,
        panel=not args.no_panel,
        pmd_size=int(extra.get("pmd_size", viewer.PMD_SIZE)),
    )
    stats = viewer.run(options)
    if args.benchmark and stats["seconds"] > 0:
        cam = scene.camera
        print(
            f"{args.benchmark} at {cam.width}x{cam.height}: "
            f"{stats['frames'] / stats['seconds']:.1f} fps over "
            f"{stats['frames']} frames ({stats['traces']} traces, {stats['reshades']} re-shades)"
        )
    if args.frames is not None and "readout" in stats:
        print("readout: " + "; ".join(stats["readout_lines"]))
    if args.screenshot is not None:
        print(f"wrote {args.screenshot}")
    return 0


def _add_accuracy(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "accuracy",
        help="measure error against run time for every knob, and the stability matrix",
        description="Write OUT/accuracy.md and OUT/figures/accuracy_*.png: each knob's error "
        "against a "
        "converged reference (uv, image, visibility) and its run time, the Pareto fronts, the "
        "shipped "
        "defaults, and the stability table of the extreme cases. 'glshade accuracy --out docs' "
        "regenerates the repository's report (a few minutes).",
    )
    p.add_argument(
        "--out",
        type=path_arg,
        default=Path("accuracy"),
        metavar="DIR",
        help="output directory (default accuracy)",
    )
    p.add_argument(
        "--repeats", type=int, default=5, metavar="K", help="timed repeats per setting (default 5)"
    )
    p.add_argument(
        "--size",
        type=int,
        default=256,
        metavar="N",
        help="pixels across for the per-frame knobs (default 256)",
    )
    p.add_argument(
        "--scenes",
        default="flat,cylinder,sphere",
        metavar="LIST",
        help="surface kinds of the knobs' paper scenes (default flat,cylinder,sphere)",
    )
    p.set_defaults(run=_cmd_accuracy)


def _cmd_accuracy(args: argparse.Namespace) -> int:
    from glshade.validation import accuracy

    if args.repeats < 1:
        raise GlshadeError(f"--repeats: must be an integer >= 1, got {args.repeats}")
    if args.out.exists() and not args.out.is_dir():
        raise GlshadeError(f"--out {args.out}: is not a directory")
    Camera().resampled(args.size)
    surfaces = tuple(part.strip() for part in args.scenes.split(",") if part.strip())
    path = accuracy.run(
        args.out,
        repeats=args.repeats,
        size=args.size,
        surfaces=surfaces,
        log=lambda m: print(m, file=sys.stderr),
    )
    print(f"wrote {path}")
    return 0


def _add_finding3(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "finding3",
        help="the paper's finding 3 under realistic optics (eq. (1) roughness, lens, Fresnel, "
        "sensor)",
        description="Measure visibility against theta for the paper's gentle and steep 5 um dents "
        "on the flat "
        "plate with the ideal mirror and with each realistic effect alone and combined; write "
        "OUT/finding3.csv, finding3.png and finding3.md ('glshade paper --out OUT' then quotes "
        "the verdicts). "
        "About 14 minutes at the default size on 2 CPU cores.",
    )
    p.add_argument(
        "--out",
        type=path_arg,
        default=Path("paper_study"),
        metavar="DIR",
        help="output directory (default paper_study)",
    )
    p.add_argument("--size", type=int, default=512, metavar="N", help="pixels across (default 512)")
    p.set_defaults(run=_cmd_finding3)


def _cmd_finding3(args: argparse.Namespace) -> int:
    from glshade.study import finding3

    if args.out.exists() and not args.out.is_dir():
        raise GlshadeError(f"--out {args.out}: is not a directory")
    Camera().resampled(args.size)
    if args.size < 256:
        raise GlshadeError(
            f"--size: must be at least 256 (the stripes need 4 pixels a period), got {args.size}"
        )
    path = finding3.run(
        args.out,
        size=args.size,
        progress=lambda row: print(
            f"{row['variant']:>13} theta {row['theta_deg']:>4g} sigma2 {row['sigma2_mm2']:>3g}: "
            f"{row['visibility_px']:g} px ({row['seconds']:.1f} s)"
            + ("" if row["status"] == "ok" else f" [{row['status']}: not measurable]"),
            file=sys.stderr,
        ),
    )
    print(f"wrote {path}")
    return 0


def _add_bench(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "bench",
        help="time the shaders (fp32, fp64) against the NumPy reference",
        description="Render the paper's flat scene (theta 45) and report the median time per frame "
        "and megapixels per second for the fp32 and fp64 shaders and the NumPy fp64 reference.",
    )
    p.add_argument(
        "--size", type=int, default=1024, metavar="N", help="pixels across (default 1024)"
    )
    p.add_argument("--theta", type=float, default=45.0, metavar="DEG")
    p.add_argument(
        "--repeats", type=int, default=9, metavar="K", help="frames timed per shader (default 9)"
    )
    p.add_argument(
        "--reference-rows", type=int, metavar="R", help="trace only R rows with NumPy and scale"
    )
    p.add_argument("--device", type=int, metavar="N", help="EGL device index")
    p.set_defaults(run=_cmd_bench)


def _add_sweep(sub: argparse._SubParsersAction) -> None:
    from glshade.app.cli_sweep import add_sweep

    add_sweep(sub)


def _add_optimize(sub: argparse._SubParsersAction) -> None:
    from glshade.app.cli_sweep import add_optimize

    add_optimize(sub)


def _add_coding(sub: argparse._SubParsersAction) -> None:
    from glshade.app.cli_coding import add_coding

    add_coding(sub)


#: Every command and the function that adds its parser, in the order ``--help`` lists them.
COMMANDS: dict[str, Callable[[argparse._SubParsersAction], None]] = {
    "render": _add_render,
    "measure": _add_measure,
    "info": _add_info,
    "paper": _add_paper,
    "view": _add_view,
    "accuracy": _add_accuracy,
    "finding3": _add_finding3,
    "bench": _add_bench,
    "sweep": _add_sweep,
    "optimize": _add_optimize,
    "coding": _add_coding,
}


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The command line's parser. ``command``: build only that command's parser (its
    flags, and the modules they need), the others as bare names, which is all a command
    line that starts with it can reach (:func:`command_of`); None: every command, whole
    (``glshade --help``)."""
    parser = Parser(
        prog="glshade",
        description="GPU deflectometry simulator (stripe reflections on glossy surfaces).",
    )
    parser.add_argument("--version", action="version", version=f"glshade {__version__}")
    parser.add_argument("--verbose", action="store_true", help=VERBOSE_HELP)
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for name, add in COMMANDS.items():
        if command is None or name == command:
            add(sub)
        else:
            sub.add_parser(name)
    for command_parser in sub.choices.values():  # also after the command: glshade paper --verbose
        command_parser.add_argument(
            "--verbose", action="store_true", default=argparse.SUPPRESS, help=VERBOSE_HELP
        )
    return parser


VERBOSE_HELP = (
    "show the libraries' log output (Dask, ...) and, for an internal error, its traceback"
)


def command_of(argv: list[str]) -> str | None:
    """The command a command line runs when it starts with one (``measure --json``);
    None otherwise (``--help``, ``--version``, nothing, a typo), for which the whole
    parser is built."""
    return argv[0] if argv and argv[0] in COMMANDS else None


def _cmd_render(args: argparse.Namespace) -> int:
    from glshade.files import check_image_output, encode_image, write_npy
    from glshade.frame import exposure_gain
    from glshade.gpu.context import GLContext
    from glshade.gpu.renderer import Renderer

    scene = scene_from_args(args)
    image_path = check_image_output(args.output, "-o", args.bits)
    uv = [("--uv", args.uv, (".npy",))] if args.uv is not None else []
    check_outputs(args, scene, [("-o", args.output, ()), *uv])
    warn(scene_warnings(scene))
    outputs = ("image", "uv") if args.uv is not None else ("image",)
    with (
        GLContext(device_index=args.device) as context,
        Renderer(context, progress=True) as renderer,
    ):
        start = time.perf_counter()
        frame = renderer.render(scene, outputs)
        seconds = time.perf_counter() - start
    image = frame.output("image")
    if not scene.active.records(scene):  # a sensor's image is already in recorded units
        image = image * exposure_gain(scene.camera.exposure, image)
    atomic_write_bytes(args.output, encode_image(image, image_path.suffix, args.bits), "-o")
    if args.uv is not None:
        write_npy(args.uv, frame.output("uv"))
    save_scene(args, scene)
    cam = scene.camera
    print(
        f"wrote {args.output} ({cam.width}x{cam.height}, {scene.surface.kind}, theta "
        f"{cam.theta_deg:g} deg, "
        f"{scene.render.precision}, {seconds * 1e3:.0f} ms)"
    )
    return 0


def _cmd_info(args: argparse.Namespace) -> int:
    from glshade.gpu.context import GLContext

    with GLContext(device_index=args.device) as context:
        info = context.info()
    print(f"glshade {__version__}")
    for line in info.lines():
        print(line)
    return 0


def _cmd_bench(args: argparse.Namespace) -> int:
    from glshade.validation import bench

    if args.repeats < 1:
        raise GlshadeError(f"--repeats: must be an integer >= 1, got {args.repeats}")
    if args.reference_rows is not None and args.reference_rows < 1:
        raise GlshadeError(f"--reference-rows: must be an integer >= 1, got {args.reference_rows}")
    Camera().resampled(args.size)  # validates --size
    timings, gl_renderer = bench.run(
        args.size, args.theta, args.repeats, args.reference_rows, args.device
    )
    print(bench.report(timings, gl_renderer, args.size, args.theta, args.repeats))
    return 0


def main(argv: list[str] | None = None, interrupts: InterruptWatch | None = None) -> int:
    """Run one command; returns its exit code (0, 2 for any error the user can fix, 130
    when interrupted, 1 for glshade's own defect). Every outcome is at most one line on
    stderr (warnings aside), never a traceback (unless ``--verbose``).

    ``argv`` None: the process's own command line (``sys.argv``), and the process ends
    when this returns: every object still alive is then frozen out of the garbage
    collector's reach, so that the interpreter's shut-down does not traverse them all
    again (about 40 ms of a short command such as ``glshade measure``).
    ``interrupts``: the entry point's record of SIGINT (an error that a Ctrl-C caused is
    reported as the interruption it was)."""
    argv_given = sys.argv[1:] if argv is None else list(argv)
    options = argv_given[: argv_given.index("--")] if "--" in argv_given else argv_given
    verbose = "--verbose" in options  # known before parsing: the parser's own errors obey it
    try:
        with guarded_warnings(verbose), reading_inputs():  # no output over what it reads
            code = _run(argv_given, verbose, interrupts)
    except KeyboardInterrupt:  # between the command's own handlers (start-up, shut-down)
        code = _interrupted(None)
    if argv is None:
        gc.freeze()
    return code


def _run(argv: list[str], verbose: bool, interrupts: InterruptWatch | None) -> int:
    """The command line ``argv`` run; every exception it lets out becomes one line."""
    args = None
    try:  # (the libraries' loggers are quietened where Dask starts: glshade.logs)
        args = build_parser(command_of(argv)).parse_args(argv)
        return args.run(args)
    except SystemExit as exc:  # --help, --version, or a usage error already printed as one line
        return exc.code if isinstance(exc.code, int) else EXIT_USAGE
    except KeyboardInterrupt:
        return _interrupted(args)
    except BrokenPipeError:  # the reader of our output went away (``| head``)
        _silence_stdout()
        return 0
    except ShaderCompileError as exc:  # a composed shader the driver refused: its lines help
        print(f"glshade: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except GlshadeError as exc:
        return _error(str(exc))
    except OSError as exc:  # the file system or the environment refused (disk full, permissions)
        where = f"{exc.filename}: " if exc.filename else ""
        return _error(f"{where}{exc.strerror or exc}")
    except MemoryError:
        return _error("out of memory; try a smaller --size or set GLSHADE_MEMORY_BUDGET_MB lower")
    except RecursionError:
        return _error(
            "the input is nested too deeply to read (a file or value of thousands of levels)"
        )
    except Exception as exc:  # a defect of glshade: one line, exit 1, how to report it
        if interrupts is not None and interrupts.seen:  # a Ctrl-C inside a C extension's import
            return _interrupted(args)
        return _defect(exc, verbose)


def _interrupted(args: argparse.Namespace | None) -> int:
    resumable = args is not None and args.command in ("paper", "sweep")
    hint = " (finished cases are saved: rerun the same command to resume)" if resumable else ""
    print(f"glshade: interrupted{hint}", file=sys.stderr)
    return EXIT_INTERRUPTED


def _defect(exc: Exception, verbose: bool) -> int:
    """An exception no check foresaw: glshade's defect, not the user's. One line naming it
    and how to report it (``--verbose`` shows the traceback too); exit code 1."""
    if verbose:
        import traceback

        traceback.print_exception(exc, file=sys.stderr)
    text = one_line(str(exc))[:300]
    print(
        f"glshade: internal error: {type(exc).__name__}{': ' if text else ''}{text} (a bug in "
        f"glshade {__version__}: please report it with the command line; --verbose shows the "
        "traceback)",
        file=sys.stderr,
    )
    return EXIT_DEFECT


def _silence_stdout() -> None:
    """Point stdout at /dev/null, so that the interpreter's final flush into a closed pipe
    says nothing."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass


@contextlib.contextmanager
def guarded_warnings(verbose: bool):
    """Python warnings (a library's, NumPy's) print as one ``glshade: warning:`` line each,
    at most once per message, unless ``verbose`` (Python's own form, with the source
    line)."""
    import warnings

    if verbose:
        yield
        return
    shown: set[str] = set()

    def one_line_warning(message, category, filename, lineno, file=None, line=None) -> None:
        text = one_line(str(message))
        if text not in shown:
            shown.add(text)
            kind = "" if issubclass(category, GlshadeWarning) else f"{category.__name__}: "
            print(f"glshade: warning: {kind}{text}", file=sys.stderr)

    with warnings.catch_warnings():
        warnings.showwarning = one_line_warning
        yield


def _error(message: str) -> int:
    print(f"glshade: error: {one_line(message)}", file=sys.stderr)
    return EXIT_USAGE


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
