"""``glshade sweep`` and ``glshade optimize`` (docs/sweeps.md): the command-line faces of
:mod:`glshade.sweep`. Bad input is one line and exit code 2, as everywhere in the CLI."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from glshade.app.args import (
    add_metric_flags,
    add_pmd_settings_flags,
    add_scene_flags,
    check_memory,
    check_outputs,
    metric_flags_given,
    metric_settings,
    path_arg,
    pmd_flags_given,
    pmd_settings,
    save_scene,
    scene_from_args,
    warn,
)
from glshade.errors import GlshadeError
from glshade.oracle.advice import scene_warnings
from glshade.sweep.goals import METRICS

if TYPE_CHECKING:  # the measuring machinery is loaded by the commands that run it
    from glshade.measure.executors import Distribution

#: Pixels across of the optimiser's scenes unless --size says otherwise.
OPTIMIZE_SIZE = 256


def _add_distribution_flags(p: argparse.ArgumentParser) -> None:
    where = p.add_mutually_exclusive_group()
    where.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help="start a local Dask cluster of N worker processes (default: run in this process); "
        "at most 2 per CPU core and as many as the memory budget holds "
        "(GLSHADE_MEMORY_BUDGET_MB)",
    )
    where.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="use an existing Dask cluster, e.g. tcp://head:8786 (dask-jobqueue, dask-cuda, ...)",
    )
    p.add_argument(
        "--connect-timeout",
        type=float,
        default=10.0,
        metavar="S",
        help="seconds joining --scheduler may take before giving up (default 10)",
    )
    p.add_argument(
        "--threads",
        type=int,
        default=2,
        metavar="N",
        help="in-process: threads for the metric's analysis (default 2, at most 2 per CPU core)",
    )
    p.add_argument(
        "--batch", type=int, default=16, metavar="K", help="Dask: most cases per task (default 16)"
    )


def _distribution(args: argparse.Namespace) -> Distribution:
    """Where the command's cases run; a --scheduler is checked here (a Dask scheduler
    answers there within --connect-timeout), before any output is written."""
    from glshade.measure.executors import Distribution

    distribution = Distribution(
        workers=args.workers,
        scheduler=args.scheduler,
        threads=args.threads,
        connect_timeout_s=args.connect_timeout,
        batch=args.batch,
        verbose=getattr(args, "verbose", False),
    )
    if distribution.scheduler is not None:
        from glshade.measure.scheduler import check_scheduler

        check_scheduler(
            distribution.scheduler, distribution.connect_timeout_s, distribution.verbose
        )
    return distribution


# --------------------------------------------------------------------------- sweep
def add_sweep(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "sweep",
        help="measure every case of a grid over any scene keys (results.parquet)",
        description="Measure the visibility of every case of a sweep file's grid (docs/sweeps.md) "
        'by the paper\'s stripe metric or, with [metric] method = "pmd", as a phase-measuring '
        "deflectometry station does, and write "
        "results.parquet and results.csv (one row per case: every swept key, every output). In "
        "this process by "
        "default, on local Dask workers with --workers, or on a cluster with --scheduler; the "
        "table is the same. "
        "Rerunning resumes: a case already measured (by the hash of its scene and metric) is "
        "never measured again.",
    )
    p.add_argument("file", type=path_arg, metavar="FILE.toml", help="the sweep file")
    p.add_argument(
        "--out", type=path_arg, metavar="DIR", help="output directory (default sweep_<file stem>)"
    )
    p.add_argument(
        "--size", type=int, metavar="N", help="pixels across, overriding the file's size"
    )
    p.add_argument(
        "--yes", action="store_true", help="run a grid of more cases than the confirmation limit"
    )
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace a sweep of another base scene, size, metric or glshade version in --out",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    _add_distribution_flags(p)
    p.set_defaults(run=_cmd_sweep)


def _cmd_sweep(args: argparse.Namespace) -> int:
    from glshade.process import reuse_freed_memory
    from glshade.sweep.run import run_sweep
    from glshade.sweep.spec import load_spec

    spec = load_spec(args.file, size=args.size, yes=args.yes)  # a big grid: refused first
    distribution = _distribution(args)
    out = args.out if args.out is not None else Path(f"sweep_{args.file.stem}")
    first = next(iter(spec.cases().chunks()))  # the budget, before --out is touched
    check_memory(
        [point.case for point in first],
        spec.settings,
        threads=distribution.threads,
        pooled=not (distribution.workers or distribution.scheduler),
    )
    warn(scene_warnings(first[0].scene))
    reuse_freed_memory()
    result = run_sweep(
        spec,
        out,
        distribution,
        yes=args.yes,
        overwrite=args.overwrite,
        progress=not args.no_progress,
        notify=lambda line: warn([line]),
    )
    rate = (
        f", {result.computed / result.seconds:.2f} cases/s"
        if result.computed and result.seconds > 0
        else ""
    )
    print(
        f"wrote {out / 'results.parquet'} and results.csv: {result.cases} cases "
        f"measured by {spec.method} ({result.computed} measured, "
        f"{result.skipped} already done) in {result.seconds:.1f} s{rate}"
    )
    counts = result.statuses
    if set(counts) - {"ok"}:
        shown = ", ".join(f"{n} {status}" for status, n in counts.items() if status != "ok")
        print(f"not measurable: {shown} (the status and status_reason columns say why)")
    return 0


# --------------------------------------------------------------------------- optimize
def add_optimize(sub: argparse._SubParsersAction) -> None:
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
        help="values per family range (default 3)",
    )
    p.add_argument(
        "--metric",
        choices=METRICS,
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
        help="most refinement evaluations (default 30; 0: none)",
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
    add_metric_flags(p)
    add_pmd_settings_flags(p)
    _add_distribution_flags(p)
    p.set_defaults(run=_cmd_optimize)


def _cmd_optimize(args: argparse.Namespace) -> int:
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
    if goal.method != "paper":
        for flag in metric_flags_given(args):
            raise GlshadeError(
                f"{flag}: belongs to the paper's stripe metric, not to --metric {args.metric}"
            )
    else:
        for flag in pmd_flags_given(args):
            raise GlshadeError(f"{flag}: belongs to the pmd metrics, not to --metric {args.metric}")

    if args.size is None:
        args.size = OPTIMIZE_SIZE
    scene = scene_from_args(args)
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
    settings = metric_settings(args) if goal.method == "paper" else pmd_settings(args)
    distribution = _distribution(args)
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
            f"{_STATUS_WORDS[goal.method]}): their viewpoints were left out of the search"
        )
    return 0


#: What makes a case unreadable, by instrument, in words.
_STATUS_WORDS = {
    "paper": "stripes unresolved, the dent at an edge or out of view, or under the noise floor",
    "pmd": "fringes averaged out, the dent at an edge or out of view, the exposure, or under "
    "the noise floor",
}


def _value_line(result, members: int) -> str:
    """The optimum's objective: the worst case over the family, in its unit."""
    goal = result.goal
    if goal.method == "paper":
        worst = f"worst case over {members} dents" if members > 1 else "visibility"
        return f"{worst} ({result.metric}): {result.value:.3f} px"
    unit = f" {goal.unit}" if goal.unit else ""
    worst = f", worst case over {members} dents" if members > 1 else ""
    sense = "maximised" if goal.sense > 0 else "minimised"
    return f"{goal.column} ({sense}{worst}): {result.value:.4g}{unit}"
