"""Running the paper's study under phase measuring: every pending case of the plan
through the executors every study and sweep measures with (in this process or on Dask
workers: :func:`glshade.measure.where.open_executor`; the engine shares one defect-free
analysis per (surface, θ, σ²) among its depths), each finished case written at once
(``pmd_cases/<key>.json``), so an interrupted run loses nothing and a rerun measures only
what is missing. The directory is locked for the run
(:func:`glshade.measure.locks.run_lock`)."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, cast

from glshade.components.emitter.fringes.table import fringes_of
from glshade.instruments.base import Case
from glshade.instruments.record import PmdMeasurement
from glshade.measure.case_files import Rejected
from glshade.measure.executors import Distribution
from glshade.measure.where import open_executor
from glshade.study.plan import PlanPoint, case_key
from glshade.study.pmd_plan import PmdStudyPlan
from glshade.study.pmd_store import (
    PMD_LAYOUT,
    RESULTS_NAME,
    PmdCaseResult,
    finished,
    write_case,
    write_results_csv,
)
from glshade.study.store import opened

if TYPE_CHECKING:
    from glshade.rendering import Renderer


@dataclass
class PmdStudyResult:
    """Every case's row in plan order, how many were measured in this run and how many
    were read back, and the seconds this run spent measuring."""

    rows: list[PmdCaseResult]
    computed: int
    skipped: int
    seconds: float
    out_dir: Path


def run_pmd_study(
    plan: PmdStudyPlan,
    out_dir: Path,
    *,
    renderer: Renderer | None = None,
    distribution: Distribution | None = None,
    progress: bool = True,
    overwrite: bool = False,
    on_case_done: Callable[[PmdCaseResult], None] | None = None,
    notify: Callable[[str], None] | None = None,
) -> PmdStudyResult:
    """Run (or resume) the PMD study into ``out_dir`` and write ``pmd_results.csv``.

    A directory whose ``pmd_study.json`` holds another plan is refused unless
    ``overwrite`` (which removes only the PMD study's files: the stripe study beside it
    is never touched). ``on_case_done(row)`` is called once a case is safely on disk;
    ``notify(line)`` is told of case files that fail their check (measured again; a
    warning when None). ``distribution``: where the cases are measured (default: this
    process, on ``renderer`` or a renderer of its own)."""
    out_dir, manifest = Path(out_dir), plan.to_dict()
    with opened(out_dir, manifest, overwrite, PMD_LAYOUT):
        rejected = Rejected()
        keys = [case_key(*point) for point in plan.cases()]
        done: dict[str, PmdCaseResult] = finished(out_dir, keys, rejected)
        pending = [point for point in plan.cases() if case_key(*point) not in done]
        rejected.say(notify)
        skipped = len(done)
        start = time.perf_counter()
        bar = _progress_bar(len(plan.cases()), skipped, progress)
        where = distribution or Distribution(threads=1)
        try:
            cases = [Case(point, plan.scene(*point)) for point in pending]
            periods = {case.key: float(fringes_of(case.scene).periods[0]) for case in cases}
            with open_executor(where, renderer) as executor:
                for key, record, _ in executor.rows(cases, plan.settings, False):
                    point = cast(PlanPoint, key)
                    row = PmdCaseResult.of_point(point, periods[key], cast(PmdMeasurement, record))
                    write_case(out_dir, row)
                    done[case_key(*point)] = row
                    if bar is not None:
                        bar.update(1)
                    if on_case_done is not None:
                        on_case_done(row)
        finally:
            if bar is not None:
                bar.close()
        seconds = time.perf_counter() - start
        rows = [done[case_key(*point)] for point in plan.cases()]
        write_results_csv(out_dir / RESULTS_NAME, rows)
    return PmdStudyResult(rows, len(pending), skipped, seconds, out_dir)


def _progress_bar(total: int, initial: int, enabled: bool):
    from glshade.progress import progress_bar

    return progress_bar(
        total, "glshade paper --method pmd", "case", initial=initial, enabled=enabled
    )
