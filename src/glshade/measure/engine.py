"""Measuring many scenes on one renderer: the engine under ``glshade paper``, ``glshade
sweep`` (in-process and on every Dask worker), ``glshade optimize`` and ``glshade finding3``.

Each case is a pure function of its scene and its instrument's settings; the settings say
the instrument (:func:`glshade.instruments.registry.instrument_for`), which measures the
cases. The engine only saves work that changes no number: the cases that share a
defect-free scene (the instrument's :meth:`~glshade.instruments.base.Instrument.geometry_key`:
the same geometry, another dent) are measured together, so the instrument analyses their
defect-free twin once; the geometries of one shader feature set run one after the other
(one program, compiled once). Before a geometry is traced, the instrument checks it
against the renderer's memory budget (:meth:`~glshade.instruments.base.Instrument.budget_plan`).
"""

from __future__ import annotations

from collections.abc import Hashable, Iterator, Sequence
from concurrent.futures import Executor
from typing import TYPE_CHECKING, Any

from glshade.gpu.compose import ShaderFeatures
from glshade.instruments.base import BudgetPlan, Case, Extra, Measured
from glshade.instruments.registry import instrument_for
from glshade.scene import Scene

if TYPE_CHECKING:
    from glshade.rendering import Renderer

#: The most cases an executor that does not say how many it runs is taken to analyse at once.
UNSAID_THREADS = 17


def geometry_key(scene: Scene, settings: Any) -> str:
    """Scenes with equal keys share their defect-free trace and analysis: the key of the
    instrument ``settings`` belong to."""
    return instrument_for(settings).geometry_key(scene, settings)


def program_key(scene: Scene) -> Hashable:
    """Scenes with equal keys run one compiled program (:class:`ShaderFeatures`)."""
    return ShaderFeatures.from_scene(scene, ("uv",))


def grouped(cases: Sequence[Case], settings: Any) -> list[list[Case]]:
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
    settings: Any,
    *,
    pool: Executor | None = None,
    extra: Extra | None = None,
) -> Iterator[Measured]:
    """Measure every case with the instrument ``settings`` belong to; yields one
    :class:`~glshade.instruments.base.Measured` per case, geometry by geometry
    (:func:`grouped`), as each is done. ``pool``: threads the instrument may analyse in
    (None: this thread); GL work stays on the calling thread. ``extra`` runs beside each
    case's numbers, with the view the instrument offers of it.

    Before a geometry is traced, its renderer's buffers and analysis (every thread's, and
    the maps waiting for them) are held against the renderer's memory budget: beyond it,
    a GlshadeError of one line."""
    chosen = instrument_for(settings)
    budget, threads = renderer.memory_budget_bytes, analysis_threads(pool)
    for group in grouped(cases, settings):
        plan = chosen.budget_plan(group[0].scene, settings, budget, threads, pool is not None)
        yield from chosen.measure_group(renderer, group, settings, pool, extra, plan)


def budget_plan(
    scene: Scene,
    settings: Any,
    budget_bytes: int,
    threads: int = 1,
    pooled: bool = False,
) -> BudgetPlan:
    """The memory check of a geometry (``scene``) before it is traced, by the instrument
    ``settings`` belong to: a GlshadeError of one line where its buffers and analysis
    exceed ``budget_bytes``, else its :class:`~glshade.instruments.base.BudgetPlan`.
    ``threads``: analysis threads; ``pooled``: the cases are analysed in a pool while the
    next are traced."""
    return instrument_for(settings).budget_plan(scene, settings, budget_bytes, threads, pooled)


def check_budget(
    cases: Sequence[Case],
    settings: Any,
    budget_bytes: int,
    threads: int = 1,
    pooled: bool = False,
) -> None:
    """:func:`budget_plan` of every geometry of ``cases``, nothing rendered: what a caller
    runs before it writes anything (a study before its directory)."""
    for group in grouped(cases, settings):
        budget_plan(group[0].scene, settings, budget_bytes, threads, pooled)


def analysis_threads(pool: Executor | None) -> int:
    """Cases ``pool`` analyses at once: its workers (a thread pool's ``_max_workers``;
    an executor that does not say is taken to run every case that may wait)."""
    if pool is None:
        return 1
    return int(getattr(pool, "_max_workers", UNSAID_THREADS))
