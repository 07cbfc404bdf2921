"""Measuring many scenes on one renderer: the engine under ``glshade paper``, ``glshade
sweep`` (in-process and on every Dask worker) and ``glshade optimize``.

Each case is a pure function of its scene and the metric settings. The engine only saves
work that changes no number: the cases that share a defect-free scene (the same geometry,
another dent) share one :class:`~glshade.metrics.visibility.Baseline`, traced and analysed
once; the geometries of one shader feature set run one after the other (one program,
compiled once). For scenes whose picture is a function of the emitter map (a mirror, a
pinhole, one ray per pixel) the GL thread keeps tracing while ``pool`` threads measure; the
others (a lens, a lobe, Fresnel, a sensor) render every phase on the GL thread
(:func:`glshade.metrics.measurement.measure_scene`).
"""

from __future__ import annotations

import json
import time
from collections import deque
from collections.abc import Callable, Hashable, Iterator, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass
from typing import Any

import numpy as np

from glshade.metrics import visibility as vis
from glshade.metrics.measurement import (
    emitter_map,
    measure_scene,
    phase_images,
    shades_from_map,
)
from glshade.scene import Scene

#: Cases traced ahead of the analysis: at most this many emitter maps wait in memory
#: (4 MiB each at 1024²).
AHEAD = 16


@dataclass(frozen=True)
class Measured:
    """One measured case: the caller's ``token`` for it, its scene, the metric's result,
    the seconds its trace took, and what the caller's ``extra`` hook made of it."""

    token: Hashable
    scene: Scene
    result: vis.Visibility
    trace_s: float
    extra: Any = None


@dataclass(frozen=True)
class CaseView:
    """What an ``extra`` hook may look at besides the result: the case's defect-free
    analysis, its emitter map ``v1`` and, for rendered shading, its phase images."""

    baseline: vis.Baseline
    v1: np.ndarray | None
    images: Callable[[float], np.ndarray] | None

    def best_image(self, scene: Scene, result: vis.Visibility) -> np.ndarray:
        """The case's radiance image at its best phase (float, [0, 1])."""
        if self.images is not None:
            return self.images(result.best_phase_mm)
        return vis.stripe_radiance(self.v1, scene.emitter, result.best_phase_mm)


#: ``extra(token, scene, result, view) -> anything``: per-case work beside the numbers
#: (thumbnails, overlays, images); it runs where the case is measured.
Extra = Callable[[Hashable, Scene, vis.Visibility, CaseView], Any]


def geometry_key(scene: Scene) -> str:
    """Scenes with equal keys share their defect-free trace and analysis."""
    return json.dumps(scene.without_defect().to_dict(), sort_keys=True, default=str)


def program_key(scene: Scene) -> Hashable:
    """Scenes with equal keys run one compiled program (:class:`ShaderFeatures`)."""
    from glshade.gpu.compose import ShaderFeatures

    return ShaderFeatures.from_scene(scene, ("uv",))


def grouped(items: Sequence[tuple[Hashable, Scene]]) -> list[list[tuple[Hashable, Scene]]]:
    """``items`` by geometry (first appearance first), the geometries of one shader
    feature set next to each other: the order the engine measures them in."""
    geometries: dict[str, list[tuple[Hashable, Scene]]] = {}
    for token, scene in items:
        geometries.setdefault(geometry_key(scene), []).append((token, scene))
    programs: dict[Hashable, list[list[tuple[Hashable, Scene]]]] = {}
    for group in geometries.values():
        programs.setdefault(program_key(group[0][1]), []).append(group)
    return [group for groups in programs.values() for group in groups]


def measure_many(
    renderer,
    items: Sequence[tuple[Hashable, Scene]],
    settings: vis.MetricSettings,
    *,
    pool: Executor | None = None,
    extra: Extra | None = None,
) -> Iterator[Measured]:
    """Measure every ``(token, scene)``; yields one :class:`Measured` per item, geometry
    by geometry (:func:`grouped`), as each is done. ``pool``: threads for the analysis of
    map-shaded cases (None: this thread). GL work stays on the calling thread."""
    for group in grouped(items):
        if shades_from_map(group[0][1]):
            yield from _mapped(renderer, group, settings, pool, extra)
        else:
            yield from _rendered(renderer, group, settings, extra)


def _mapped(renderer, group, settings, pool, extra) -> Iterator[Measured]:
    """One geometry shaded from its emitter maps: trace here, analyse in ``pool``."""
    normal = group[0][1].without_defect()
    baseline = vis.Baseline(emitter_map(renderer, normal), normal.emitter, settings)
    waiting: deque = deque()
    for token, scene in group:
        start = time.perf_counter()
        v1 = emitter_map(renderer, scene)
        trace_s = time.perf_counter() - start
        if pool is None:
            yield _analyse(token, scene, baseline, v1, trace_s, extra)
            continue
        waiting.append(pool.submit(_analyse, token, scene, baseline, v1, trace_s, extra))
        while len(waiting) > AHEAD or (waiting and waiting[0].done()):
            yield waiting.popleft().result()
    while waiting:
        yield waiting.popleft().result()


def _analyse(token, scene, baseline, v1, trace_s, extra) -> Measured:
    result = baseline.measure(v1)
    made = extra(token, scene, result, CaseView(baseline, v1, None)) if extra is not None else None
    return Measured(token, scene, result, trace_s, made)


def _rendered(renderer, group, settings, extra) -> Iterator[Measured]:
    """One geometry whose pictures are rendered phase by phase, all on this thread."""
    from glshade.metrics.measurement import baseline_for

    baseline = baseline_for(renderer, group[0][1], settings)
    for token, scene in group:
        start = time.perf_counter()
        v1 = emitter_map(renderer, scene)
        trace_s = time.perf_counter() - start
        result = measure_scene(renderer, scene, settings, baseline, v1=v1)
        made = None
        if extra is not None:
            made = extra(
                token, scene, result, CaseView(baseline, v1, phase_images(renderer, scene))
            )
        yield Measured(token, scene, result, trace_s, made)
