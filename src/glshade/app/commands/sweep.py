"""``glshade sweep`` (docs/sweeps.md): every case of a sweep file's grid measured, by the
instrument the file's ``[metric] method`` names. Bad input is one line and exit code 2,
as everywhere in the CLI."""

from __future__ import annotations

import argparse
from pathlib import Path

from glshade.app.args import check_memory, check_station, path_arg, warn
from glshade.app.commands.distribution import add_distribution_flags, distribution_of
from glshade.oracle.advice import scene_warnings


def add(sub: argparse._SubParsersAction) -> None:
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
    add_distribution_flags(p)


def run(args: argparse.Namespace) -> int:
    from glshade.process import reuse_freed_memory
    from glshade.sweep.run import run_sweep
    from glshade.sweep.spec import load_spec

    spec = load_spec(args.file, size=args.size, yes=args.yes)  # a big grid: refused first
    distribution = distribution_of(args)
    out = args.out if args.out is not None else Path(f"sweep_{args.file.stem}")
    first = next(iter(spec.cases().chunks()))  # the budget, before --out is touched
    check_memory(
        [point.case for point in first],
        spec.settings,
        threads=distribution.threads,
        pooled=not (distribution.workers or distribution.scheduler),
    )
    warn(scene_warnings(first[0].scene))
    check_station(first[0].scene)  # a posed station that shows no screen: one line
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
