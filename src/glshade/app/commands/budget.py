"""``glshade budget`` (docs/budget.md): a phase-measuring station's uncertainty budget.
The believed geometry is drawn from a budget file's standard deviations, one input at a
time and all together, each draw measured by phase measuring (in this process, on local
Dask workers or on a cluster, as a sweep's cases), and what each input contributes to the
slope map, the fitted depth and the dent's position is written as a table and a figure.
Bad input is one line and exit code 2, with nothing written."""

from __future__ import annotations

import argparse
from pathlib import Path

from glshade.app.args import (
    add_scene_flags,
    add_settings_flags,
    check_outputs,
    instrument_settings,
    path_arg,
    save_scene,
    scene_from_args,
    scene_measure_table,
    warn,
)
from glshade.app.commands.distribution import add_distribution_flags, distribution_of
from glshade.errors import GlshadeError

#: Pixels across of the budget's scenes unless --size says otherwise.
BUDGET_SIZE = 128


def add(sub: argparse._SubParsersAction) -> None:
    from glshade.uncertainty.spec import DEFAULT_DRAWS, DEFAULT_SEED

    p = sub.add_parser(
        "budget",
        help="a PMD station's uncertainty budget: what each calibration error does to slopes, "
        "depth and the dent's position",
        description="Draw the geometry a phase-measuring station believes from the standard "
        "deviations of a budget file (--uncertainty: [uncertainty] maps dotted parameter paths, "
        'camera.position[0], camera.focal, emitter.distance, ..., to σ, "0.5%%" of the true '
        "value allowed; docs/budget.md), one input at a time and all together, measure every "
        "draw with the frames rendered from the truth, and write what each input contributes "
        "to the slope map (rms, rms with its uniform tilt removed, and at the dent, µrad), the "
        "fitted depth (µm) and the dent's shift (mm), and the total, as budget.csv, budget.md "
        "and budget.png in --out; the table is printed too. On a flat mirror the camera's and "
        "the screen's pose are checked against their closed forms. Scenes are rendered at "
        "--size (default "
        f"{BUDGET_SIZE}). Rerunning resumes.",
    )
    add_scene_flags(p)
    p.add_argument(
        "--uncertainty",
        required=True,
        type=path_arg,
        metavar="BUDGET.toml",
        help="the budget file: [uncertainty] path = σ, optional draws and seed",
    )
    p.add_argument(
        "-o",
        "--out",
        type=path_arg,
        metavar="DIR",
        help="output directory (default budget_<scene stem>, or budget without a scene file)",
    )
    p.add_argument(
        "--draws",
        type=int,
        metavar="N",
        help=f"draws per input and for the total (default the file's, else {DEFAULT_DRAWS})",
    )
    p.add_argument(
        "--draw-seed",
        dest="draw_seed",
        type=int,
        metavar="N",
        help=f"the draws' seed (default the file's seed, else {DEFAULT_SEED}; --seed is the "
        "sensor's noise seed)",
    )
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace a budget of another scene, settings, inputs or glshade version in --out",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_settings_flags(p, "pmd")
    add_distribution_flags(p)


def run(args: argparse.Namespace) -> int:
    from glshade.oracle.advice import scene_warnings
    from glshade.process import reuse_freed_memory
    from glshade.uncertainty.checks import closed_form_checks
    from glshade.uncertainty.report import (
        budget_rows,
        closed_form_lines,
        summary_lines,
        table_lines,
    )
    from glshade.uncertainty.run import run_budget, truth_of
    from glshade.uncertainty.spec import DRAWS_RANGE, MAX_SEED, load_budget

    if args.draws is not None and not DRAWS_RANGE[0] <= args.draws <= DRAWS_RANGE[1]:
        raise GlshadeError(
            f"--draws: must be an integer in [{DRAWS_RANGE[0]}, {DRAWS_RANGE[1]}], got {args.draws}"
        )
    if args.draw_seed is not None and not 0 <= args.draw_seed <= MAX_SEED:
        raise GlshadeError(
            f"--draw-seed: must be an integer in [0, {MAX_SEED}], got {args.draw_seed}"
        )
    if args.size is None:
        args.size = BUDGET_SIZE
    scene = scene_from_args(args)
    table = scene_measure_table(args, scene)
    settings = instrument_settings(args, "pmd", "glshade budget", table)
    truth = truth_of(scene)
    spec = load_budget(args.uncertainty, truth, args.draws, args.draw_seed)
    check_outputs(args, scene, [])
    out = args.out if args.out is not None else Path(_default_out(args))
    distribution = distribution_of(args)
    if scene.calibration:
        warn(["the scene's [calibration] is left out: the reference believes the truth"])
    warn(scene_warnings(truth))
    reuse_freed_memory()
    result = run_budget(
        scene,
        spec,
        settings,
        out,
        distribution,
        overwrite=args.overwrite,
        progress=not args.no_progress,
        notify=lambda line: warn([line]),
    )
    save_scene(args, scene)
    rows = budget_rows(result)
    print(f"{truth.title()}; {truth.camera.width}x{truth.camera.height} pixels, phase measuring")
    for line in table_lines(rows):
        print(line)
    for line in summary_lines(result, rows):
        print(line)
    checks = closed_form_checks(result)
    if checks:
        print("closed-form checks (flat mirror, first order):")
        for line in closed_form_lines(checks):
            print(line)
    total = len(result.draws)
    print(
        f"wrote {out / 'budget.csv'}, budget.md, budget.png and draws.csv: {total} draws "
        f"({result.computed} measured, {result.skipped} already done) in {result.seconds:.1f} s"
    )
    return 0


def _default_out(args: argparse.Namespace) -> str:
    return f"budget_{args.scene.stem}" if args.scene is not None else "budget"
