"""Where ``glshade sweep``'s and ``glshade optimize``'s cases run: their ``--workers``,
``--scheduler``, ``--threads`` and ``--batch`` flags and the
:class:`~glshade.measure.executors.Distribution` they describe."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the measuring machinery is loaded by the commands that run it
    from glshade.measure.executors import Distribution


def add_distribution_flags(p: argparse.ArgumentParser) -> None:
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


def distribution_of(args: argparse.Namespace) -> Distribution:
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
