"""``glshade coding`` (docs/coding.md): the command-line face of
:mod:`glshade.instruments.pmd.coding`, choosing a PMD station's fringe coding for a scene. Bad
input is one line and exit code 2, as everywhere in the CLI."""

from __future__ import annotations

import argparse
import json
import math

from glshade.app.args import (
    add_scene_flags,
    argument_type,
    check_outputs,
    length_mm,
    path_arg,
    save_scene,
    scene_from_args,
    warn,
)
from glshade.errors import GlshadeError
from glshade.oracle.advice import scene_warnings

#: Flag -> the :class:`~glshade.instruments.pmd.coding.CodingSettings` field it sets.
CODING_FLAGS = {
    "--target-noise": "target_noise_mm",
    "--resolved-share": "resolved_share",
    "--margin": "margin_sigmas",
    "--candidates": "candidates",
}


def add(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "coding",
        help="choose a PMD station's fringe coding: finest period, shifts, period ladder",
        description="For a scene (TOML file or the paper's flat plate; a scene of stripes "
        "shows fringes on the same screen) render the defect-free scene's modulation against "
        "the fringe period through the whole chain, and answer: the finest period it "
        "resolves, the shifts N and the period ladder that reach --target-noise and unwrap "
        "safely, the unambiguous and slope ranges, the dent's SNR. Noise needs a sensor "
        "(e.g. --set sensor.full_well_e=10000); a real pixel's averaging needs "
        "--supersample 4 or more. docs/coding.md explains every number.",
    )
    add_scene_flags(p)
    p.add_argument(
        "--target-noise",
        type=argument_type("length", length_mm),
        metavar="LENGTH",
        help="the decoded screen coordinate's noise to reach, mm or with a unit (2um); "
        "default: keep the scene's emitter.shifts",
    )
    p.add_argument(
        "--resolved-share",
        type=float,
        metavar="X",
        help="a period is resolved where its modulation keeps this share of a sharp "
        "mirror's (default 0.5)",
    )
    p.add_argument(
        "--margin",
        type=float,
        metavar="SIGMAS",
        help="unwrapping margin: a period's phase error (this many σ of noise plus the "
        "screen's systematic bounds) times the ratio to the next finer stays below π "
        "(default 6)",
    )
    p.add_argument(
        "--candidates",
        type=int,
        metavar="N",
        help="periods probed, log-spaced from one pixel's footprint to the coarsest (default 24)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    p.add_argument(
        "--plot", type=path_arg, metavar="PNG", help="also plot modulation against period"
    )
    p.add_argument(
        "--coded-scene",
        type=path_arg,
        metavar="SCENE.toml",
        help="also write the scene with the recommended coding (emitter.periods, shifts)",
    )


def coding_settings(args: argparse.Namespace):
    """The :class:`~glshade.instruments.pmd.coding.CodingSettings` of the command line, a bad
    value named by its flag."""
    from glshade.instruments.pmd.coding import CodingSettings

    given = {
        field: getattr(args, field_dest(flag))
        for flag, field in CODING_FLAGS.items()
        if getattr(args, field_dest(flag)) is not None
    }
    try:
        return CodingSettings(**given)
    except GlshadeError as exc:
        field, _, rest = str(exc).partition(":")
        flag = next(f for f, name in CODING_FLAGS.items() if name == field)
        raise GlshadeError(f"{flag}:{rest}") from None


def field_dest(flag: str) -> str:
    return flag.lstrip("-").replace("-", "_")


def run(args: argparse.Namespace) -> int:
    from glshade.gpu.context import GLContext
    from glshade.gpu.renderer import Renderer
    from glshade.instruments.pmd.coding import choose_coding
    from glshade.instruments.pmd.coding_files import coded_scene, summary, write_plot
    from glshade.instruments.pmd.settings import check_scene
    from glshade.measure.single import as_method

    settings = coding_settings(args)
    scene = as_method(scene_from_args(args), "pmd")
    check_scene(scene)
    outputs = [
        (flag, path, suffixes)
        for flag, path, suffixes in (
            ("--plot", args.plot, (".png",)),
            ("--coded-scene", args.coded_scene, (".toml",)),
        )
        if path is not None
    ]
    check_outputs(args, scene, outputs)
    warn(scene_warnings(scene))
    with (
        GLContext(device_index=args.device) as context,
        Renderer(context, progress=True) as renderer,
    ):
        report = choose_coding(renderer, scene, settings)
    if args.plot is not None:
        write_plot(report, args.plot)
    if args.coded_scene is not None:
        coded_scene(report).save(args.coded_scene)
    save_scene(args, scene)
    if args.json:
        print(json.dumps(summary(report)))
        return 0
    for line in report_lines(report):
        print(line)
    for flag, path in (("--plot", args.plot), ("--coded-scene", args.coded_scene)):
        if path is not None:
            print(f"  wrote {path} ({flag})")
    return 0


# --------------------------------------------------------------------------- text
def _mm(value: float, fmt: str = ".3g") -> str:
    return "n/a" if not math.isfinite(value) else format(value, fmt)


def _share(value: float, width: int) -> str:
    """A share in a table column (``n/a`` where there is no closed form)."""
    return f"{value:{width}.3f}" if math.isfinite(value) else f"{'n/a':>{width}}"


def _margin(value: float) -> str:
    """An unwrapping margin in σ (infinite: no noise to count it in)."""
    return "∞ (no noise)" if value == math.inf else _mm(value)


def report_lines(report) -> list[str]:
    """The report as text: each number with its unit and meaning; an unreadable one says
    why."""
    return [
        *_header(report),
        *_modulation_lines(report),
        *_coding_lines(report),
        *_current_lines(report),
        *_range_lines(report),
        *(f"  note: {note}" for note in report.notes),
    ]


def _header(report) -> list[str]:
    scene = report.scene
    cam, sensor = scene.camera, scene.sensor
    lens = "pinhole" if cam.f_number <= 0 else f"f/{cam.f_number:g} lens"
    noise = (
        f"sensor: full well {sensor.full_well_e:g} e-, read noise {sensor.read_noise_e:g} e-, "
        f"{sensor.bit_depth} bit"
        if report.sensor
        else "no sensor"
    )
    return [
        f"{scene.title()} ({cam.width}x{cam.height}, supersample {scene.render.supersample}, "
        f"{lens}; {noise})"
    ]


def _modulation_lines(report) -> list[str]:
    probe = report.probe
    where = "the dent's window" if probe.in_window else "every pixel that sees the screen"
    dirs = probe.directions
    lines = [
        f"Modulation against fringe period (median over {where}, {probe.pixels} pixels; share "
        "of a sharp mirror's)",
        "  period mm   " + "".join(f"{d} rendered  closed form  " for d in dirs) + "real pixel",
    ]
    for c, period in enumerate(probe.periods_mm):
        cells = "".join(
            f"{_share(probe.share[i, c], 10)}  {_share(report.closed_form[i, c], 11)}  "
            for i in range(len(dirs))
        )
        lines.append(f"  {period:9.4g}  {cells}{_share(report.pixel_box[0, c], 10)}")
    seen = ", ".join(f"{_mm(report.footprint_mm[d], '.4g')} mm along {d}" for d in dirs)
    blur = ", ".join(f"{_mm(report.blur_mm[d], '.4g')} mm along {d}" for d in dirs)
    lines.append(f"  one pixel sees {seen} of the screen; the lens blurs over {blur}")
    if not all(math.isfinite(report.footprint_mm[d]) for d in dirs):
        lines.append(
            "  closed form n/a: the base focuses the screen at the gaze point (no finite "
            "magnification); the rendered shares stand alone"
        )
    lines.append(
        "  closed form: box footprint w sampled as rendered, |sin x / (n sin(x/n))|, x = π w / "
        "p, times a lens's disc 2 J1(π b / p) / (π b / p); real pixel: |sin x / x|"
    )
    return lines + [_resolved_line(report)]


def _resolved_line(report) -> str:
    level = report.settings.resolved_share
    each = ", ".join(f"{d} {_mm(r.period_mm)} mm" for d, r in report.resolved_each.items())
    r = report.resolved
    why = "" if r.status == "ok" else f" [{r.status}: {r.reason}]"
    return (
        f"  finest resolved period   {_mm(r.period_mm)} mm (modulation share >= {level:g}; "
        f"{each}){why}"
    )


def _coding_lines(report) -> list[str]:
    rec, settings = report.recommended, report.settings
    de = report.scene.gaze.screen_mm
    target = settings.target_noise_mm
    aim = f"a noise of {target:g} mm" if target is not None else "the scene's shifts"
    lines = [f"Recommended coding (for {aim}; margin {settings.margin_sigmas:g} σ)"]
    if rec.status == "unresolved":
        return lines + [f"  not available [{rec.status}: {rec.reason}]"]
    why = "least noise among the resolved periods" if report.sensor else "the finest resolved"
    how = (
        "the smallest reaching the target"
        if target is not None and report.sensor
        else ("the scene's emitter.shifts")
    )
    periods = ", ".join(f"{p:g}" for p in rec.periods_mm)
    ratios = ", ".join(f"{r:.3g}" for r in rec.ratios)
    flag = "" if rec.status in ("ok", "over_budget") else f"  [{rec.status}: {rec.reason}]"
    lines += [
        f"  finest period p1         {rec.periods_mm[0]:g} mm ({why}; share {rec.share:.2f})",
        f"  shifts N                 {rec.shifts} ({how}){flag}",
        f"  predicted noise          {_mm(rec.noise_mm)} mm on the screen, p1/2π sqrt(2/N) "
        f"σ_I/B (a slope noise of {_mm(1e6 * rec.noise_mm / (2 * de))} µrad)"
        + ("" if report.sensor else "; no sensor, no noise"),
        f"  periods (K = {len(rec.periods_mm)})          {periods} mm (ratios {ratios}; the "
        f"worst step keeps {_margin(rec.margin_sigmas)} σ of margin)",
        f"  screen's fixed patterns  quantisation {_mm(rec.quantisation_mm)} mm rms (at most "
        f"{_mm(rec.quantisation_bound_mm)}), gamma aliasing {_mm(rec.gamma_mm)} mm (the same in "
        "every capture: not in the noise)",
        f"  emitter settings         --set emitter.periods={periods.replace(' ', '')} "
        f"--set emitter.shifts={rec.shifts}",
        _memory_line(report, rec),
    ]
    if target is not None and rec.quantisation_mm > target:
        lines.append(
            f"  note: the screen's quantisation ({_mm(rec.quantisation_mm)} mm rms) exceeds the "
            "target: a fixed pattern, not noise; a screen of more emitter.levels lowers it"
        )
    return lines


def _memory_line(report, plan) -> str:
    """What measuring ``plan`` takes against the memory budget; beyond it, the status
    with the budget it needs."""
    from glshade.instruments.memory import size_text

    budget = report.budget_bytes / (1 << 20)
    if plan.status == "over_budget":
        fits = f"[{plan.status}: {plan.reason}]"
    elif plan.memory_bytes > report.budget_bytes:
        fits = f"more than the memory budget of {budget:.0f} MiB"
    else:
        fits = f"within the memory budget of {budget:.0f} MiB"
    return (
        f"  memory                   {size_text(plan.memory_bytes)} for {plan.frames} frames "
        f"(glshade measure --method pmd; GLSHADE_MEMORY_BUDGET_MB >= {plan.budget_mib}) {fits}"
    )


def _current_lines(report) -> list[str]:
    cur = report.current
    periods = ", ".join(f"{p:g}" for p in cur.periods_mm)
    flag = "" if cur.status == "ok" else f"  [{cur.status}: {cur.reason}]"
    lines = [
        f"The scene's own coding (periods {periods} mm, N {cur.shifts}){flag}",
        f"  predicted noise {_mm(cur.noise_mm)} mm; worst unwrapping margin "
        f"{_margin(cur.margin_sigmas)} σ; finest period's share {_mm(cur.share, '.2f')}",
    ]
    if cur.memory_bytes:
        from glshade.instruments.memory import size_text

        lines.append(
            f"  memory {size_text(cur.memory_bytes)} for {cur.frames} frames "
            f"(GLSHADE_MEMORY_BUDGET_MB >= {cur.budget_mib})"
        )
    return lines


def _range_lines(report) -> list[str]:
    rng, rec, cur = report.ranges, report.recommended, report.current
    screen = ", ".join(f"{v:g} mm along {d}" for d, v in rng.screen_mm.items())
    slopes = ", ".join(f"±{_mm(v)} mrad along {d}" for d, v in rng.slope_range_mrad.items())
    flag = "" if rng.status == "ok" else f"  [{rng.status}: {rng.reason}]"
    law = "" if rng.shift_status == "ok" else f"  [{rng.shift_status}: {rng.shift_reason}]"
    snr_law = "" if rng.shift_status == "ok" else f"  [{rng.shift_status}: the dent's shift]"
    u, v = rng.screen_point_mm
    return [
        "Ranges",
        f"  unambiguous range        {rng.unambiguous_mm:g} mm (the coarsest period; the screen "
        f"spans {screen})",
        f"  dent's screen point      u {_mm(u, '.2f')} mm, v {_mm(v, '.2f')} mm{flag}",
        f"  slope range              {slopes} (the screen's edge from the dent's screen point: "
        f"(half_size - |point|) / 2 De){flag}",
        f"  dent's shift             {rng.dent_shift_mm:.4g} mm on the screen (closed form; a "
        f"slope of about {rng.dent_slope_mrad:.3g} mrad){law}",
        f"  expected SNR             {_snr(rng.dent_shift_mm, rec.noise_mm)} with the recommended "
        f"coding, {_snr(rng.dent_shift_mm, cur.noise_mm)} with the scene's{snr_law}",
    ]


def _snr(shift: float, noise: float) -> str:
    if not math.isfinite(noise):
        return "n/a"
    return "inf (no noise)" if noise == 0 else f"{shift / noise:.0f}"
