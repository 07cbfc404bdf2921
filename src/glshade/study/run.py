"""Running the paper's study on a renderer: trace, measure, write, in a pipeline.

Every case is measured by the one metric pipeline (:class:`glshade.metrics.visibility.Baseline`):
for every (surface, θ) the defect-free scene is traced once and its analysis is shared by
the 8 (σ², dmax) cases of that geometry, which changes no number (a case is a pure
function of its scene and the metric settings; ``tests/test_study.py`` checks the rows
against :func:`glshade.measure`). The cases run through the sweep engine
(:mod:`glshade.measure.engine`, the machinery of ``glshade sweep`` too): the GL work stays on
the calling thread; the analysis runs in ``workers`` threads. What is swept is
:mod:`glshade.study.plan`; what is written,
and resumed from, :mod:`glshade.study.store`.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import cv2
import numpy as np

from glshade.errors import GlshadeError
from glshade.files import encode_png
from glshade.gpu.renderer import Renderer
from glshade.instruments.base import Case, Measured
from glshade.instruments.record import Measurement
from glshade.instruments.stripes.group import CaseView
from glshade.measure.case_files import Rejected
from glshade.measure.executors import Distribution
from glshade.measure.where import open_executor
from glshade.metrics import contours
from glshade.metrics import visibility as vis
from glshade.study.plan import (
    GRID_THETAS,
    OVERLAY_CASES,
    THUMBNAIL,
    PlanPoint,
    StudyPlan,
    case_key,
)
from glshade.study.store import (
    CaseResult,
    finished,
    opened,
    write_cases,
    write_results_csv,
)


@dataclass
class Timings:
    """Seconds spent per stage over a run (what ``docs/BENCHMARKS.md`` reports)."""

    trace: float = 0.0
    shade: float = 0.0
    contours: float = 0.0
    continuous: float = 0.0
    io: float = 0.0
    figures: float = 0.0


@dataclass
class StudyResult:
    rows: list[CaseResult]
    timings: Timings
    computed: int
    skipped: int
    out_dir: Path


class _Progress:
    """Which cases are done, the progress bar, and the callbacks of :func:`run_study`."""

    def __init__(
        self,
        plan: StudyPlan,
        keys: dict[PlanPoint, str],
        done: dict[str, CaseResult],
        pending: list[PlanPoint],
        bar,
        on_case_done,
        on_surface_done,
    ) -> None:
        self.plan, self.keys, self.done, self.bar = plan, keys, done, bar
        self.on_case_done, self.on_surface_done = on_case_done, on_surface_done
        self.left = {
            surface: sum(case[0] == surface for case in pending) for surface in plan.surfaces
        }

    def finished(self, row: CaseResult) -> None:
        self.done[self.keys[row.case]] = row
        if self.bar is not None:
            self.bar.update(1)
        if self.on_case_done is not None:
            self.on_case_done(row)
        self.left[row.surface] -= 1
        if self.left[row.surface] == 0 and self.on_surface_done is not None:
            self.on_surface_done(row.surface, self.rows(row.surface))

    def rows(self, surface: str | None = None) -> list[CaseResult]:
        """The finished rows in plan order (of one surface, or all)."""
        keys = [key for point, key in self.keys.items() if surface is None or point[0] == surface]
        return [self.done[key] for key in keys if key in self.done]


def run_study(
    plan: StudyPlan,
    out_dir: Path,
    *,
    workers: int = 1,
    progress: bool = True,
    renderer: Renderer | None = None,
    on_case_done: Callable[[CaseResult], None] | None = None,
    on_surface_done: Callable[[str, list[CaseResult]], None] | None = None,
    overwrite: bool = False,
    distribution: Distribution | None = None,
    notify: Callable[[str], None] | None = None,
) -> StudyResult:
    """Run (or resume) the study into ``out_dir``; returns every case's record.

    The directory is locked for the run (:func:`glshade.measure.locks.run_lock`: a second
    run on it is
    refused); a directory holding another plan is refused unless ``overwrite``, which
    removes the old study's files first (:func:`glshade.study.store.opened`).

    ``workers``: threads for the analysis (the GL work stays on this thread).
    ``distribution``: measure elsewhere instead (:class:`~glshade.measure.executors.
    Distribution`: local Dask worker processes, each tracing and analysing whole
    geometries, or an existing cluster); the figures' thumbnails are made there too, the
    files are written here.
    ``on_case_done(row)`` is called after each case is on disk (the cases of a geometry
    are written together, :func:`_run_cases`);
    ``on_surface_done(surface, rows)`` once the last case of a surface computed in this
    run is, with all of that surface's rows (the CLI draws its figures there, on this
    thread, while the workers measure the next surface).
    ``notify(line)`` is told of case files that fail their check (they are measured
    again; a warning when None).
    """
    check_workers(workers)
    out_dir, manifest = Path(out_dir), plan.to_dict()
    with opened(out_dir, manifest, overwrite):
        where = distribution or Distribution(threads=workers)
        return _run_locked(
            plan, out_dir, where, progress, renderer, (on_case_done, on_surface_done), notify
        )


def check_workers(workers: int) -> None:
    """The analysis threads of a run in one process: at least one, at most two per CPU
    core (:func:`glshade.measure.capacity.check_threads`)."""
    from glshade.measure.capacity import check_threads

    if workers < 1:
        raise GlshadeError(f"--threads: must be an integer >= 1, got {workers}")
    check_threads(workers)


def _run_locked(plan, out_dir, distribution, progress, renderer, callbacks, notify) -> StudyResult:
    on_case_done, on_surface_done = callbacks
    rejected = Rejected()
    keys = {point: case_key(*point) for point in plan.cases()}  # in the plan's order
    done: dict[str, CaseResult] = finished(out_dir, list(keys.values()), rejected)
    pending = [point for point, key in keys.items() if key not in done]
    rejected.say(notify)
    skipped = len(done)
    state = _Progress(
        plan,
        keys,
        done,
        pending,
        _progress_bar(len(plan.cases()), skipped, progress),
        on_case_done,
        on_surface_done,
    )
    timings = Timings()
    try:
        if pending:
            with open_executor(distribution, renderer) as executor:
                _run_cases(plan, pending, executor, timings, out_dir, state.finished)
    finally:
        if state.bar is not None:
            state.bar.close()
    rows = state.rows()
    start = time.perf_counter()
    write_results_csv(out_dir / "results.csv", rows)
    timings.io += time.perf_counter() - start
    return StudyResult(
        rows=rows, timings=timings, computed=len(rows) - skipped, skipped=skipped, out_dir=out_dir
    )


def _progress_bar(total: int, initial: int, enabled: bool):
    from glshade.progress import progress_bar

    return progress_bar(total, "glshade paper", "case", initial=initial, enabled=enabled)


def _run_cases(
    plan: StudyPlan,
    points: list[PlanPoint],
    executor,
    timings: Timings,
    out_dir: Path,
    finished: Callable[[CaseResult], None],
) -> None:
    """Measure every pending case with the measuring engine
    (:func:`glshade.measure.engine.measure_many`: one defect-free analysis per (surface,
    θ); in this process the GL thread traces while the pool measures, on workers each
    measures whole geometries) and write the cases of a geometry together as soon as its
    last one is done (:func:`_write`: one flush for the group). Interrupted, the cases
    measured by then are written still."""
    cases = [Case(point, plan.scene(*point)) for point in points]
    left = Counter(_geometry(point) for point in points)
    groups: dict[tuple[str, float], list[tuple[CaseResult, CaseFigures]]] = {}
    try:
        for measured in executor.measured(cases, plan.metric, _figures):
            row = case_result(measured)
            timings.trace += measured.trace_s
            geometry = _geometry(row.case)
            groups.setdefault(geometry, []).append((row, measured.extra))
            left[geometry] -= 1
            if not left[geometry]:
                _finished(_write(groups.pop(geometry), timings, out_dir), finished)
        for geometry in list(groups):
            _finished(_write(groups.pop(geometry), timings, out_dir), finished)
    finally:
        for group in groups.values():  # interrupted: the cases measured by then are kept
            _write(group, timings, out_dir)


def _geometry(point: PlanPoint) -> tuple[str, float]:
    """The (surface, θ) of a case: the cases that share a defect-free trace."""
    return point[0], point[1]


def _finished(rows: list[CaseResult], finished: Callable[[CaseResult], None]) -> None:
    for row in rows:
        finished(row)


@dataclass(frozen=True)
class CaseFigures:
    """What a case leaves for the study's figures: its thumbnail at the best phase (the
    θ of the figure grids) and its Fig. 9 overlay (its cases): the overlay's colours,
    the result, the first kept column and the case's title."""

    thumbnail: bytes | None
    overlay: tuple[np.ndarray, vis.Visibility, int, str] | None


def _figures(case: Case, result: vis.Visibility, view: CaseView) -> CaseFigures:
    """A case's figures, made where the case is measured."""
    thumbnail = overlay = None
    point, scene = cast(PlanPoint, case.key), case.scene
    if point[1] in GRID_THETAS:
        image = view.best_image(scene, result)
        small = cv2.resize(image, (THUMBNAIL, THUMBNAIL), interpolation=cv2.INTER_AREA)
        thumbnail = encode_png(small, bits=8)
    if point in OVERLAY_CASES:
        normal, defect = view.baseline.stripes_at(
            view.v1, result.best_phase_mm, result.offset_px, view.images
        )
        rgb = contours.overlay_rgb(normal, defect)
        overlay = (rgb, result, view.baseline.columns.start, scene.title())
    return CaseFigures(thumbnail, overlay)


def _write(
    group: list[tuple[CaseResult, CaseFigures]], timings: Timings, out_dir: Path
) -> list[CaseResult]:
    """A group of finished cases on disk (the overlay figures among them first), with one
    flush for the group (:func:`glshade.study.store.write_cases`); their rows."""
    start = time.perf_counter()
    for row, figures in group:
        timings.shade += row.shade_s
        timings.contours += row.contours_s
        timings.continuous += row.continuous_s
        if figures.overlay is not None:
            from glshade.instruments.figures import overlay_figure

            rgb, result, first_column, title = figures.overlay
            overlay_figure(
                rgb, result, first_column, title, out_dir / OVERLAY_CASES[row.case], within=out_dir
            )
    write_cases(out_dir, [(row, figures.thumbnail) for row, figures in group])
    timings.io += time.perf_counter() - start
    return [row for row, _ in group]


def case_result(measured: Measured) -> CaseResult:
    """A case's row: its point of the plan and its measurement's record."""
    case = measured.case
    point = cast(PlanPoint, case.key)
    record = cast(Measurement, measured.record)  # the paper's study: the stripe metric
    return CaseResult.of_point(point, case.scene.emitter.period, record)
