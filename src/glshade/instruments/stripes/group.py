"""The paper's stripe metric over the cases of one geometry: its defect-free analysis
(:class:`~glshade.metrics.visibility.Baseline`) made once and shared. For scenes whose
picture is a function of the emitter map (a mirror, a pinhole, one ray per pixel) the GL
thread keeps tracing while ``pool`` threads measure; the others (a lens, a lobe, Fresnel,
a sensor) render every phase on the GL thread
(:func:`glshade.instruments.stripes.single.measure_scene`)."""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from glshade.instruments.base import BudgetPlan, Case, Extra, Measured
from glshade.instruments.memory import check_paper, paper_estimate
from glshade.instruments.record import Measurement
from glshade.instruments.stripes.single import (
    baseline_for,
    emitter_map,
    judged,
    map_baseline,
    measure_scene,
    phase_images,
    shades_from_map,
)
from glshade.metrics import visibility as vis
from glshade.scene import Scene

if TYPE_CHECKING:
    from glshade.rendering import Renderer

#: Cases traced ahead of the analysis: at most this many emitter maps wait in memory
#: (4 MiB each at 1024²; fewer where the memory budget cannot hold them, :func:`ahead_within`).
AHEAD = 16


@dataclass(frozen=True)
class CaseView:
    """What an ``extra`` hook may look at besides the result: the case's defect-free
    analysis, its emitter map ``v1`` and, for rendered shading, its phase images."""

    baseline: vis.Baseline
    v1: np.ndarray
    images: Callable[[float], np.ndarray] | None

    def best_image(self, scene: Scene, result: vis.Visibility) -> np.ndarray:
        """The case's radiance image at its best phase (float, [0, 1])."""
        if self.images is not None:
            return self.images(result.best_phase_mm)
        return vis.stripe_radiance(self.v1, self.baseline.pattern, result.best_phase_mm)


def ahead_within(
    scene: Scene, settings: vis.MetricSettings, threads: int, budget_bytes: int
) -> int:
    """Cases to trace ahead of ``threads`` analysis threads: :data:`AHEAD`, halved until
    the memory estimate fits ``budget_bytes`` (0 at least; the order of the results and
    every number stay the same, only the overlap of tracing and analysis shrinks)."""

    def need(ahead: int) -> int:
        return paper_estimate(scene, settings, threads, ahead + 1).required_bytes

    ahead = AHEAD
    while ahead and need(ahead) > budget_bytes:
        ahead //= 2
    return ahead


def _traced(renderer: Renderer, case: Case) -> tuple[np.ndarray, float]:
    """A case's emitter map and the seconds its trace took."""
    start = time.perf_counter()
    v1 = emitter_map(renderer, case.scene)
    return v1, time.perf_counter() - start


def _mapped(
    renderer: Renderer,
    group: list[Case],
    settings: vis.MetricSettings,
    pool: Executor | None,
    extra: Extra | None,
    plan: BudgetPlan,
) -> Iterator[Measured]:
    """One geometry shaded from its emitter maps: trace here, analyse in ``pool``, at most
    ``plan.ahead`` cases traced ahead of the analysis."""
    normal = group[0].scene.without_defect()
    baseline = map_baseline(normal, emitter_map(renderer, normal), settings, plan.cache_bytes)
    ahead = plan.ahead
    waiting: deque = deque()
    for case in group:
        v1, trace_s = _traced(renderer, case)
        if pool is None:
            yield _analyse(case, baseline, v1, trace_s, extra)
            continue
        waiting.append(pool.submit(_analyse, case, baseline, v1, trace_s, extra))
        while len(waiting) > ahead or (waiting and waiting[0].done()):
            yield waiting.popleft().result()
    while waiting:
        yield waiting.popleft().result()


def _analyse(
    case: Case, baseline: vis.Baseline, v1: np.ndarray, trace_s: float, extra: Extra | None
) -> Measured:
    result = judged(case.scene, baseline, v1, baseline.measure(v1))
    made = extra(case, result, CaseView(baseline, v1, None)) if extra is not None else None
    return Measured(case, result, Measurement.of(case.scene, result, trace_s), trace_s, made)


def _rendered(
    renderer: Renderer,
    group: list[Case],
    settings: vis.MetricSettings,
    extra: Extra | None,
    cache_bytes: int,
) -> Iterator[Measured]:
    """One geometry whose pictures are rendered phase by phase, all on this thread."""
    baseline = baseline_for(renderer, group[0].scene, settings, cache_bytes)
    for case in group:
        v1, trace_s = _traced(renderer, case)
        result = measure_scene(renderer, case.scene, settings, baseline, v1=v1)
        made = None
        if extra is not None:
            view = CaseView(baseline, v1, phase_images(renderer, case.scene))
            made = extra(case, result, view)
        yield Measured(case, result, Measurement.of(case.scene, result, trace_s), trace_s, made)


def budget_plan(
    scene: Scene,
    settings: vis.MetricSettings,
    budget_bytes: int,
    threads: int = 1,
    pooled: bool = False,
) -> BudgetPlan:
    """The memory check of a geometry (``scene``) before it is traced: a GlshadeError of one
    line where its renderer's buffers and analysis exceed ``budget_bytes``
    (:mod:`glshade.instruments.memory`), else its plan. ``threads``: analysis threads;
    ``pooled``: the maps are analysed in a pool while the next are traced. The caller
    holds the last result while the next case is measured."""
    if not shades_from_map(scene):
        return BudgetPlan(check_paper(scene, settings, budget_bytes, waiting=1).cache_bytes, 0)
    ahead = ahead_within(scene, settings, threads, budget_bytes) if pooled else 0
    waiting = ahead + 1 if pooled else 1  # the most futures queued, or the caller's last
    found = check_paper(scene, settings, budget_bytes, threads, waiting)
    return BudgetPlan(found.cache_bytes, ahead)


def measure_group(
    renderer: Renderer,
    group: Sequence[Case],
    settings: vis.MetricSettings,
    pool: Executor | None,
    extra: Extra | None,
    plan: BudgetPlan,
) -> Iterator[Measured]:
    """One geometry's cases: shaded from their emitter maps, or rendered phase by phase."""
    if shades_from_map(group[0].scene):
        return _mapped(renderer, list(group), settings, pool, extra, plan)
    return _rendered(renderer, list(group), settings, extra, plan.cache_bytes)
