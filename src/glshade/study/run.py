"""Running the paper's study on a renderer: trace, measure, write, in a pipeline.

Every case is measured by the one metric pipeline (:class:`glshade.metrics.visibility.Baseline`):
for every (surface, θ) the defect-free scene is traced once and its analysis is shared by
the 8 (σ², dmax) cases of that geometry, which changes no number (a case is a pure
function of its scene and the metric settings; ``tests/test_study.py`` checks the rows
against :func:`glshade.measure`). The GL work stays on the calling thread; the analysis
runs in ``workers`` threads. What is swept is :mod:`glshade.study.plan`; what is written,
and resumed from, :mod:`glshade.study.store`.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from glshade.errors import GlshadeError
from glshade.files import encode_png
from glshade.gpu.renderer import Renderer
from glshade.metrics import contours, physics
from glshade.metrics import visibility as vis
from glshade.metrics.measurement import baseline_for, emitter_map, measure_scene, phase_images, shades_from_map
from glshade.scene import Scene
from glshade.study.plan import (
    GRID_THETAS,
    OVERLAY_CASES,
    THUMBNAIL,
    Case,
    StudyPlan,
    case_key,
)
from glshade.study.store import (
    CaseResult,
    load_case,
    prepare_out_dir,
    study_lock,
    write_case,
    write_results_csv,
)

#: Cases traced ahead of the analysis: the GL thread keeps tracing while the workers
#: measure, and at most this many emitter maps wait in memory (4 MiB each at 1024²).
_AHEAD = 16


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

    def __init__(self, plan: StudyPlan, done: dict[str, CaseResult], pending: list[Case], bar, on_case_done,
                 on_surface_done) -> None:
        self.plan, self.done, self.bar = plan, done, bar
        self.on_case_done, self.on_surface_done = on_case_done, on_surface_done
        self.left = {surface: sum(case[0] == surface for case in pending) for surface in plan.surfaces}

    def finished(self, row: CaseResult) -> None:
        self.done[case_key(*row.case)] = row
        if self.bar is not None:
            self.bar.update(1)
        if self.on_case_done is not None:
            self.on_case_done(row)
        self.left[row.surface] -= 1
        if self.left[row.surface] == 0 and self.on_surface_done is not None:
            self.on_surface_done(row.surface, self.rows(row.surface))

    def rows(self, surface: str | None = None) -> list[CaseResult]:
        """The finished rows in plan order (of one surface, or all)."""
        keys = [case_key(*c) for c in self.plan.cases() if surface is None or c[0] == surface]
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
) -> StudyResult:
    """Run (or resume) the study into ``out_dir``; returns every case's record.

    The directory is locked for the run (:func:`store.study_lock`: a second run on it is
    refused); a directory holding another plan is refused unless ``overwrite``, which
    removes the old study's files first (:func:`store.prepare_out_dir`).

    ``workers``: threads for the analysis (the GL work stays on this thread).
    ``on_case_done(row)`` is called after each case is safely on disk;
    ``on_surface_done(surface, rows)`` once the last case of a surface computed in this
    run is, with all of that surface's rows (the CLI draws its figures there, on this
    thread, while the workers measure the next surface).
    """
    check_workers(workers)
    out_dir = Path(out_dir)
    with study_lock(out_dir):
        prepare_out_dir(out_dir, plan.to_dict(), overwrite)
        return _run_locked(plan, out_dir, workers, progress, renderer, on_case_done, on_surface_done)


def check_workers(workers: int) -> None:
    """The analysis threads of a run: at least one."""
    if workers < 1:
        raise GlshadeError(f"--workers: must be an integer >= 1, got {workers}")


def _run_locked(plan, out_dir, workers, progress, renderer, on_case_done, on_surface_done) -> StudyResult:
    done: dict[str, CaseResult] = {}
    pending = []
    for case in plan.cases():
        row = load_case(out_dir / "cases" / f"{case_key(*case)}.json")
        if row is not None:
            done[case_key(*case)] = row
        else:
            pending.append(case)
    skipped = len(done)
    state = _Progress(plan, done, pending, _progress_bar(len(plan.cases()), skipped, progress), on_case_done,
                      on_surface_done)
    timings = Timings()
    owns = renderer is None
    renderer = renderer or Renderer()
    try:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            _run_cases(plan, pending, renderer, pool, timings, out_dir, state.finished)
    finally:
        if state.bar is not None:
            state.bar.close()
        if owns:
            renderer.release()
    rows = state.rows()
    start = time.perf_counter()
    write_results_csv(out_dir / "results.csv", rows)
    timings.io += time.perf_counter() - start
    return StudyResult(rows=rows, timings=timings, computed=len(rows) - skipped, skipped=skipped, out_dir=out_dir)


def _progress_bar(total: int, initial: int, enabled: bool):
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, unit="case", desc="glshade paper", dynamic_ncols=True)


def _run_cases(plan: StudyPlan, cases: list[Case], renderer: Renderer, pool: ThreadPoolExecutor, timings: Timings,
               out_dir: Path, finished: Callable[[CaseResult], None]) -> None:
    """Trace every pending case on this (the GL) thread, measure it in the pool, and
    write each result as soon as it is done, in order. The defect-free trace and analysis
    of a (surface, θ) is made once and shared by its cases (:class:`vis.Baseline` labels
    the normal stripes of a phase the first time a worker needs them)."""
    waiting: deque = deque()

    def drain(keep: int) -> None:
        """Write what is done at the head of the queue; wait while more than ``keep`` wait."""
        while len(waiting) > keep or (waiting and waiting[0].done()):
            row, thumbnail, overlay = waiting.popleft().result()
            _write(row, thumbnail, overlay, timings, out_dir)
            finished(row)

    for group in plan.geometries(cases):
        normal_scene = plan.scene(*group[0]).without_defect()
        if not shades_from_map(normal_scene):
            _run_rendered(plan, group, renderer, timings, out_dir, finished)
            continue
        start = time.perf_counter()
        baseline = vis.Baseline(emitter_map(renderer, normal_scene), normal_scene.emitter, plan.metric)
        timings.trace += time.perf_counter() - start
        for case in group:
            scene = plan.scene(*case)
            start = time.perf_counter()
            v1 = emitter_map(renderer, scene)
            trace_s = time.perf_counter() - start
            timings.trace += trace_s
            waiting.append(pool.submit(_analyse_case, case, scene, baseline, v1, trace_s))
            drain(keep=_AHEAD)
    drain(keep=0)


def _run_rendered(plan: StudyPlan, group: list[Case], renderer: Renderer, timings: Timings, out_dir: Path,
                  finished: Callable[[CaseResult], None]) -> None:
    """The cases of one geometry whose pictures are not a function of the uv map (a
    lens, a lobe, Fresnel, a sensor): every phase rendered, all on this (the GL) thread."""
    first = plan.scene(*group[0])
    start = time.perf_counter()
    baseline = baseline_for(renderer, first, plan.metric)
    timings.trace += time.perf_counter() - start
    for case in group:
        scene = plan.scene(*case)
        start = time.perf_counter()
        result = measure_scene(renderer, scene, plan.metric, baseline)
        seconds = time.perf_counter() - start
        trace_s = max(0.0, seconds - result.seconds.shade - result.seconds.contours - result.seconds.continuous)
        row = case_result(case, scene, result, trace_s)
        thumbnail = overlay = None
        images = phase_images(renderer, scene)
        if case[1] in GRID_THETAS:
            image = images(result.best_phase_mm)
            thumbnail = encode_png(cv2.resize(image, (THUMBNAIL, THUMBNAIL), interpolation=cv2.INTER_AREA), bits=8)
        if case in OVERLAY_CASES:
            normal, defect = baseline.stripes_at(emitter_map(renderer, scene), result.best_phase_mm, result.offset_px,
                                                 images)
            overlay = (contours.overlay_rgb(normal, defect), result, baseline.columns.start, scene.title())
        _write(row, thumbnail, overlay, timings, out_dir)
        finished(row)


def _write(row: CaseResult, thumbnail: bytes | None, overlay, timings: Timings, out_dir: Path) -> None:
    """A finished case on disk (its overlay figure first, when it is one of those)."""
    timings.shade += row.shade_s
    timings.contours += row.contours_s
    timings.continuous += row.continuous_s
    start = time.perf_counter()
    if overlay is not None:
        from glshade.study.plots import overlay_figure

        overlay_figure(*overlay, out_dir / OVERLAY_CASES[row.case])
    write_case(out_dir, row, thumbnail)
    timings.io += time.perf_counter() - start


def case_result(case: Case, scene: Scene, result: vis.Visibility, trace_s: float) -> CaseResult:
    """A case's record: its parameters, its measurement, the closed forms, the timings."""
    surface, theta, sigma2, dmax = case
    law = physics.laws(scene)
    summary = result.summary()
    measured = ("visibility_px", "visibility_continuous_px", "deflection_px", "folded", "islands", "best_phase_mm",
                "unpaired_contours", "unresolved_fraction")
    return CaseResult(
        surface=surface, theta_deg=theta, sigma2_mm2=sigma2, dmax_mm=dmax, period_mm=scene.emitter.period,
        **{k: summary[k] for k in measured},
        offset_dx_px=result.offset_px[0], offset_dy_px=result.offset_px[1],
        fold_ratio=round(law.fold_ratio, 5),
        deflection_law_px=round(law.deflection_px, 4),
        visibility_law_px=round(law.visibility_px, 4),
        trace_s=round(trace_s, 4), shade_s=round(result.seconds.shade, 4),
        contours_s=round(result.seconds.contours, 4), continuous_s=round(result.seconds.continuous, 4),
    )


def _analyse_case(case: Case, scene: Scene, baseline: vis.Baseline, v1: np.ndarray, trace_s: float):
    """Everything after the trace, for one case (runs in a worker thread)."""
    result = baseline.measure(v1)
    row = case_result(case, scene, result, trace_s)
    thumbnail = None
    if case[1] in GRID_THETAS:
        image = vis.stripe_radiance(v1, scene.emitter, result.best_phase_mm)
        thumbnail = encode_png(cv2.resize(image, (THUMBNAIL, THUMBNAIL), interpolation=cv2.INTER_AREA), bits=8)
    overlay = None
    if case in OVERLAY_CASES:
        normal, defect = baseline.stripes_at(v1, result.best_phase_mm, result.offset_px)
        overlay = (contours.overlay_rgb(normal, defect), result, baseline.columns.start, scene.title())
    return row, thumbnail, overlay
