"""``glshade paper --method paper``: the paper's study measured by the stripe metric
(binarised stripe edges), its figures and report.md (:class:`StripeStudy`)."""

from __future__ import annotations

import argparse
import functools
import time
from typing import Any

from glshade.app.args import (
    add_settings_flags,
    check_memory,
    instrument_settings,
    settings_flags_given,
    warn,
)
from glshade.app.studies import StudyKind, measure_table_of
from glshade.oracle.advice import scene_warnings
from glshade.process import reuse_freed_memory
from glshade.study.plan import StudyPlan


class StripeStudy(StudyKind):
    """The stripe metric's study: results.csv, the image grids, the visibility plots, the
    Fig. 9 contour overlays and report.md."""

    name = "paper"
    writes = "binarised stripe edges: results.csv, figures and report.md"

    def add_flags(self, parser: argparse.ArgumentParser) -> None:
        add_settings_flags(parser, self.name)

    def flags_given(self, args: argparse.Namespace) -> list[str]:
        return settings_flags_given(args, self.name)

    def plan_settings(self, args: argparse.Namespace) -> Any:
        return instrument_settings(args, self.name)

    def prepared(self, args: argparse.Namespace, plan: StudyPlan, workers: str) -> None:
        """The memory budget of each surface's first case, and the scenes' warnings."""
        from glshade.instruments.base import Case

        firsts = [(surface, *plan.cases()[0][1:]) for surface in plan.surfaces]
        check_memory(
            [Case(point, plan.scene(*point)) for point in firsts],
            plan.metric,
            threads=args.threads,
            pooled=not args.workers,
        )
        first_theta = plan.thetas[0]
        warn(
            line
            for sigma2 in plan.sigma2s
            for dmax in plan.dmaxs
            for line in scene_warnings(plan.scene(plan.surfaces[0], first_theta, sigma2, dmax))
        )

    def sweep_file(self, plan: StudyPlan, prepared: Any) -> dict[str, Any]:
        return {
            "size": plan.size,
            "grid": plan.sweep_grid(),
            "measure": measure_table_of(self.name, plan.metric),
        }

    def run(self, args: argparse.Namespace, plan: StudyPlan, prepared: Any) -> int:
        return run_stripes(args, plan)


def run_stripes(args: argparse.Namespace, plan: StudyPlan) -> int:
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
