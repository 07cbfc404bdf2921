"""Measuring many scenes on one renderer: the engine under ``glshade paper``, ``glshade
sweep`` (in-process and on every Dask worker), ``glshade optimize`` and ``glshade finding3``.

Each case is a pure function of its scene and the metric settings. The engine only saves
work that changes no number: the cases that share a defect-free scene (the same geometry,
another dent) share one :class:`~glshade.metrics.visibility.Baseline`, traced and analysed
once; the geometries of one shader feature set run one after the other (one program,
compiled once). For scenes whose picture is a function of the emitter map (a mirror, a
pinhole, one ray per pixel) the GL thread keeps tracing while ``pool`` threads measure; the
others (a lens, a lobe, Fresnel, a sensor) render every phase on the GL thread
(:func:`glshade.measure.single.measure_scene`).
"""

from __future__ import annotations

import json
import time
from collections import deque
from collections.abc import Callable, Hashable, Iterator, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from glshade.gpu.compose import ShaderFeatures
from glshade.measure.memory import check_paper, check_pmd, paper_estimate
from glshade.measure.pmd import PmdBaseline, PmdResult, PmdSettings, measure_pmd_scene, pmd_baseline
from glshade.measure.record import Measurement, PmdMeasurement
from glshade.measure.single import (
    baseline_for,
    emitter_map,
    judged,
    map_baseline,
    map_baseline_key,
    measure_scene,
    phase_images,
    shades_from_map,
)
from glshade.metrics import visibility as vis
from glshade.scene import Scene

if TYPE_CHECKING:
    from glshade.gpu.renderer import Renderer

#: Cases traced ahead of the analysis: at most this many emitter maps wait in memory
#: (4 MiB each at 1024²; fewer where the memory budget cannot hold them, :func:`ahead_within`).
AHEAD = 16


@dataclass(frozen=True)
class Case:
    """One scene to measure and the key its caller knows it by (a sweep's case id, the
    study's point of its plan)."""

    key: Hashable
    scene: Scene


@dataclass(frozen=True)
class Measured:
    """One measured case: the case, the metric's result, the seconds its trace took, and
    what the caller's ``extra`` hook made of it."""

    case: Case
    result: vis.Visibility | PmdResult
    trace_s: float
    extra: Any = None

    @property
    def record(self) -> Measurement | PmdMeasurement:
        """The case's row: :class:`glshade.measure.record.Measurement` of the paper's
        metric, or :class:`~glshade.measure.record.PmdMeasurement` of phase measuring."""
        if isinstance(self.result, PmdResult):
            return PmdMeasurement.of(self.case.scene, self.result)
        return Measurement.of(self.case.scene, self.result, self.trace_s)


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


#: ``extra(case, result, view) -> anything``: per-case work beside the numbers
#: (thumbnails, overlays, images); it runs where the case is measured.
Extra = Callable[[Case, vis.Visibility, CaseView], Any]


def geometry_key(scene: Scene, settings: vis.MetricSettings | PmdSettings | None = None) -> str:
    """Scenes with equal keys share their defect-free trace and analysis: the scene without
    its defect; measured by the paper's metric from the emitter map (``settings`` not
    :class:`PmdSettings`), :func:`~glshade.measure.single.map_baseline_key`, which leaves
    out the width of the absent dent (phase measuring's nominal geometry and a sensor's
    noise read the whole scene)."""
    if not isinstance(settings, PmdSettings) and shades_from_map(scene):
        return map_baseline_key(scene)
    return json.dumps(scene.without_defect().to_dict(), sort_keys=True, default=str)


def program_key(scene: Scene) -> Hashable:
    """Scenes with equal keys run one compiled program (:class:`ShaderFeatures`)."""
    return ShaderFeatures.from_scene(scene, ("uv",))


def grouped(
    cases: Sequence[Case], settings: vis.MetricSettings | PmdSettings | None = None
) -> list[list[Case]]:
    """``cases`` by geometry (:func:`geometry_key`; first appearance first), the
    geometries of one shader feature set next to each other: the order the engine
    measures them in."""
    geometries: dict[str, list[Case]] = {}
    for case in cases:
        geometries.setdefault(geometry_key(case.scene, settings), []).append(case)
    programs: dict[Hashable, list[list[Case]]] = {}
    for group in geometries.values():
        programs.setdefault(program_key(group[0].scene), []).append(group)
    return [group for groups in programs.values() for group in groups]


def measure_many(
    renderer: Renderer,
    cases: Sequence[Case],
    settings: vis.MetricSettings | PmdSettings,
    *,
    pool: Executor | None = None,
    extra: Extra | None = None,
) -> Iterator[Measured]:
    """Measure every case; yields one :class:`Measured` per case, geometry by geometry
    (:func:`grouped`), as each is done. ``pool``: threads for the analysis of map-shaded
    cases (None: this thread). GL work stays on the calling thread.

    ``settings`` says the instrument: :class:`~glshade.metrics.visibility.MetricSettings`
    the paper's stripe metric, :class:`~glshade.measure.pmd.PmdSettings` phase measuring
    (every case's emitter shows the fringe sequence; one defect-free analysis per
    geometry; ``extra`` gets a :class:`PmdView`).

    Before a geometry is traced, its renderer's buffers and analysis (every thread's, and
    the maps waiting for them) are held against the renderer's memory budget: beyond it,
    a GlshadeError of one line (:mod:`glshade.measure.memory`); the defect-free stripe
    maps kept take what the budget leaves."""
    budget, threads = renderer.memory_budget_bytes, analysis_threads(pool)
    for group in grouped(cases, settings):
        plan = budget_plan(group[0].scene, settings, budget, threads, pool is not None)
        if isinstance(settings, PmdSettings):
            yield from _phase_measured(renderer, group, settings, extra)
        elif shades_from_map(group[0].scene):
            yield from _mapped(renderer, group, settings, pool, extra, plan)
        else:
            yield from _rendered(renderer, group, settings, extra, plan.cache_bytes)


@dataclass(frozen=True)
class BudgetPlan:
    """How one geometry is measured within the memory budget: the stripe maps its
    baseline keeps (bytes) and the cases traced ahead of the analysis threads."""

    cache_bytes: int
    ahead: int


def budget_plan(
    scene: Scene,
    settings: vis.MetricSettings | PmdSettings,
    budget_bytes: int,
    threads: int = 1,
    pooled: bool = False,
) -> BudgetPlan:
    """The memory check of a geometry (``scene``) before it is traced: a GlshadeError of one
    line where its renderer's buffers and analysis exceed ``budget_bytes``
    (:mod:`glshade.measure.memory`), else its :class:`BudgetPlan`. ``threads``: analysis
    threads; ``pooled``: the maps are analysed in a pool while the next are traced. The
    caller holds the last result while the next case is measured."""
    if isinstance(settings, PmdSettings):
        check_pmd(scene, budget_bytes, results=1)
        return BudgetPlan(0, 0)
    if not shades_from_map(scene):
        return BudgetPlan(check_paper(scene, settings, budget_bytes, waiting=1).cache_bytes, 0)
    ahead = ahead_within(scene, settings, threads, budget_bytes) if pooled else 0
    waiting = ahead + 1 if pooled else 1  # the most futures queued, or the caller's last
    found = check_paper(scene, settings, budget_bytes, threads, waiting)
    return BudgetPlan(found.cache_bytes, ahead)


def check_budget(
    cases: Sequence[Case],
    settings: vis.MetricSettings | PmdSettings,
    budget_bytes: int,
    threads: int = 1,
    pooled: bool = False,
) -> None:
    """:func:`budget_plan` of every geometry of ``cases``, nothing rendered: what a caller
    runs before it writes anything (a study before its directory)."""
    for group in grouped(cases, settings):
        budget_plan(group[0].scene, settings, budget_bytes, threads, pooled)


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


def analysis_threads(pool: Executor | None) -> int:
    """Cases ``pool`` analyses at once: its workers (a thread pool's ``_max_workers``;
    an executor that does not say is taken to run every case that may wait)."""
    if pool is None:
        return 1
    return int(getattr(pool, "_max_workers", AHEAD + 1))


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
    return Measured(case, result, trace_s, made)


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
        yield Measured(case, result, trace_s, made)


@dataclass(frozen=True)
class PmdView:
    """What an ``extra`` hook of a phase-measured case may look at: its defect-free
    analysis (the result carries the case's maps)."""

    baseline: PmdBaseline


def _phase_measured(
    renderer: Renderer,
    group: list[Case],
    settings: PmdSettings,
    # an Extra that takes a PmdResult and a PmdView (see measure_many)
    extra: Callable[..., Any] | None,
) -> Iterator[Measured]:
    """One geometry measured as a PMD station measures it, its defect-free analysis once."""
    baseline = pmd_baseline(renderer, group[0].scene, settings)
    for case in group:
        result = measure_pmd_scene(renderer, case.scene, settings, baseline)
        made = extra(case, result, PmdView(baseline)) if extra is not None else None
        yield Measured(case, result, result.seconds.get("render", 0.0), made)
