"""``glshade optimize`` (docs/sweeps.md): the viewpoint that maximises a dent's (worst-case)
visibility or a phase-measuring station's number (``--metric``; :func:`run` chooses the
instrument). Bad input is one line and exit code 2, as everywhere in the CLI."""

from __future__ import annotations

import argparse
import json
import sys
import time

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
from glshade.instruments.registry import instrument
from glshade.oracle.advice import scene_warnings

#: Pixels across of the optimiser's scenes unless --size says otherwise.
OPTIMIZE_SIZE = 256


def add(sub: argparse._SubParsersAction) -> None:
    from glshade.sweep.goals import metric_names

    p = sub.add_parser(
        "optimize",
        help="find the viewpoint that maximises (worst-case) visibility or a PMD station's SNR",
        description="Find the values of the --over keys (camera elevation, rig azimuth, stripe "
        "period, ...) that "
        "maximise the dent's visibility (or a phase-measuring station's number, --metric pmd_*), "
        "or its worst case over a --family of dents: a coarse "
        "grid on the sweep "
        "machinery, then a bounded Nelder-Mead refinement (docs/sweeps.md). Prints the optimum, "
        "its visibility, "
        "how flat it is; --plot draws the objective. Scenes are rendered at --size (default "
        f"{OPTIMIZE_SIZE}).",
    )
    add_scene_flags(p)
    p.add_argument(
        "--over",
        required=True,
        metavar="KEY[=LO..HI][,...]",
        help="keys to optimise and their bounds, e.g. camera.theta_deg,camera.azimuth_deg=0..90 "
        "(theta defaults to 5..85, azimuth to 0..180)",
    )
    p.add_argument(
        "--family",
        metavar="SPEC",
        help='defects to guard against, e.g. "defect.sigma2=1..16,defect.dmax=0.003..0.005" '
        "(ranges sampled at --family-points values) or defect.sigma2=1|4|9",
    )
    p.add_argument(
        "--family-points",
        type=int,
        default=3,
        metavar="N",
        help="values per family range (default %(default)s)",
    )
    p.add_argument(
        "--metric",
        choices=metric_names(),
        default="paper",
        help="paper: whole-pixel contour shift (docs/study.md); continuous: its sub-pixel limit; "
        "pmd_snr, pmd_shift_mm, pmd_depth_um, pmd_slope_urad: a phase-measuring station's "
        "numbers, maximised; pmd_noise_mm: its noise, minimised (pmd_snr and pmd_noise_mm "
        "need a sensor). pmd_* show the fringe sequence on the scene's screen (default paper)",
    )
    p.add_argument(
        "--grid",
        type=int,
        metavar="N",
        help="coarse grid points per key (default 9, 7 for two keys, 5)",
    )
    p.add_argument(
        "--refine",
        type=int,
        default=30,
        metavar="K",
        help="most refinement evaluations (default %(default)s; 0: none)",
    )
    p.add_argument(
        "--plot", type=path_arg, metavar="PNG", help="write the objective's curve or map"
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument(
        "--yes",
        action="store_true",
        help="run a search of more cases (viewpoints x family members) than the confirmation limit",
    )
    add_settings_flags(p)
    add_distribution_flags(p)


def run(args: argparse.Namespace) -> int:
    from glshade.measure.single import as_method
    from glshade.measure.where import open_executor
    from glshade.process import reuse_freed_memory
    from glshade.sweep.optimize import (
        check_cases,
        family_members,
        goal_of,
        objective_figure,
        optimize_scene,
        parse_family_axes,
        parse_over,
    )

    goal = goal_of(args.metric)
    if args.size is None:
        args.size = OPTIMIZE_SIZE
    scene = scene_from_args(args)
    table = scene_measure_table(args, scene)
    settings = instrument_settings(args, goal.method, f"--metric {args.metric}", table)
    dimensions = parse_over(args.over)
    if not 1 <= args.family_points <= 64:
        raise GlshadeError(
            f"--family-points: must be an integer in [1, 64], got {args.family_points}"
        )
    if not 0 <= args.refine <= 1000:
        raise GlshadeError(f"--refine: must be an integer in [0, 1000], got {args.refine}")
    family_axes = parse_family_axes(args.family, args.family_points)
    check_cases(dimensions, family_axes, args.grid, args.refine, args.yes)  # before any member
    family = family_members(family_axes)
    plot = [("--plot", args.plot, (".png",))] if args.plot is not None else []
    check_outputs(args, scene, plot)
    distribution = distribution_of(args)
    warn(scene_warnings(as_method(scene, goal.method)))
    reuse_freed_memory()
    start = time.perf_counter()
    with open_executor(distribution) as executor:
        result = optimize_scene(
            scene,
            dimensions,
            family,
            metric=args.metric,
            settings=settings,
            executor=executor,
            grid_points=args.grid,
            refine_evaluations=args.refine,
        )
    seconds = time.perf_counter() - start
    save_scene(args, scene)
    if args.plot is not None:
        objective_figure(result, args.plot)
    if args.json:
        print(json.dumps({**result.summary(), "seconds": round(seconds, 2)}))
        return 0
    where = ", ".join(f"{key} = {value:g}" for key, value in result.optimum.items())
    print(f"optimum: {where}")
    print(_value_line(result, len(family)))
    for key, (lo, hi) in result.near_optimal.items():
        print(f"  {result.near_text()}: {key} in [{lo:g}, {hi:g}]")
    print(
        f"{result.evaluations} viewpoints ({result.grid_count} on the grid), {result.cases} "
        f"cases, {seconds:.1f} s" + (f"; plot: {args.plot}" if args.plot is not None else ""),
        file=sys.stdout,
    )
    if result.unmeasurable:
        shown = ", ".join(f"{n} {status}" for status, n in result.unmeasurable_statuses.items())
        print(
            f"{result.unmeasurable} of {result.cases} cases were not measurable ({shown}: "
            f"{instrument(goal.method).unreadable_words}): their viewpoints were left out of the "
            "search"
        )
    return 0


def _value_line(result, members: int) -> str:
    """The optimum's objective: the worst case over the family, in its unit."""
    from glshade.sweep.goals import unit

    goal = result.goal
    if goal.quantity:  # a named quantity (the paper's visibility), three decimals
        worst = f"worst case over {members} dents" if members > 1 else goal.quantity
        return f"{worst} ({result.metric}): {result.value:.3f} {unit(goal)}"
    shown = unit(goal)
    unit_text = f" {shown}" if shown else ""
    worst = f", worst case over {members} dents" if members > 1 else ""
    sense = "maximised" if goal.sense > 0 else "minimised"
    return f"{goal.column} ({sense}{worst}): {result.value:.4g}{unit_text}"
