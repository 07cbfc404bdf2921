"""Where ``glshade sweep``'s and ``glshade optimize``'s cases run: their ``--workers``,
``--scheduler``, ``--threads`` and ``--batch`` flags and the
:class:`~glshade.measure.executors.Distribution` they describe."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

from glshade.app.args import add_run_flags

if TYPE_CHECKING:  # the measuring machinery is loaded by the commands that run it
    from glshade.measure.executors import Distribution


def add_distribution_flags(p: argparse.ArgumentParser) -> None:
    """Where a sweep's or an optimisation's cases run: ``--workers`` or ``--scheduler``
    (one of them), ``--connect-timeout``, ``--threads`` and ``--batch``."""
    add_run_flags(p.add_mutually_exclusive_group(), ("workers", "scheduler"))
    add_run_flags(p, ("connect_timeout", "threads", "batch"))


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
