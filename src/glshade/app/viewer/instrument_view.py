"""The viewer's instrument views: the maps every registered instrument offers
(:meth:`glshade.instruments.base.Instrument.views`), measured in a thread of its own
with a renderer of its own, shown as colour maps, with the instrument's numbers in the
readout. The viewer knows no instrument by name: a view's case is the scene as its
instrument measures it (:meth:`~glshade.instruments.base.Instrument.prepared`: a scene of
stripes is measured by phase measuring with the fringe sequence on the same screen), at
the instrument's size, and the map, hover and readout are the instrument's."""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from glshade.app.viewer.colourbar import ColourScale, colour_mapped
from glshade.components.plugin_guard import PluginRefused, run_plugin_code
from glshade.errors import GlshadeError, GlshadeWarning
from glshade.instruments.base import Instrument, InstrumentView, InstrumentViews, ViewMap
from glshade.scene import Scene

if TYPE_CHECKING:
    from glshade.instruments.registry import Instruments
    from glshade.instruments.table import MeasureTable
    from glshade.rendering import Renderer

#: The views the viewer computes itself from its traces: the camera image, its
#: defect-free twin, the Fig. 9 contour overlay and the displacement.
STRIPE_VIEWS = ("image", "defect-free", "overlay", "displacement")


@dataclass(frozen=True)
class OfferedView:
    """One view an instrument offers: the instrument, all it offers, and the view."""

    instrument: Instrument
    offer: InstrumentViews
    view: InstrumentView


def instrument_views(found: Instruments | None = None) -> dict[str, OfferedView]:
    """Every view the instruments of ``found`` (default: the registry) offer, by name, in
    the registry's order. An instrument whose offer fails or does not fit (a name taken
    already) is left out with one warning naming it."""
    from glshade.instruments.registry import instruments

    out: dict[str, OfferedView] = {}
    for item in (found or instruments()).by_name.values():
        try:
            offer = run_plugin_code(item.views)
            offered = _offered(item, offer, set(out) | set(STRIPE_VIEWS))
        except PluginRefused as exc:
            warnings.warn(f"instrument {item.name!r}: views left out: {exc}", GlshadeWarning, 2)
            continue
        out.update((o.view.name, o) for o in offered)
    return out


def _offered(item: Instrument, offer: Any, taken: set[str]) -> list[OfferedView]:
    if offer is None:
        return []
    if not isinstance(offer, InstrumentViews):
        raise PluginRefused(f"views() must give InstrumentViews, got {type(offer).__name__}")
    names = [view.name for view in offer.views]
    clash = [name for name in names if name in taken or names.count(name) > 1]
    if clash:
        raise PluginRefused(f"view {clash[0]!r} is offered twice")
    return [OfferedView(item, offer, view) for view in offer.views]


def case_scene(instrument: Instrument, scene: Scene, size: int) -> Scene:
    """The scene an instrument view measures: ``scene`` (its stripes' phase already
    dropped) as ``instrument`` measures it, ``size`` pixels across (the same field of
    view) where that is fewer than the image's."""
    measured = instrument.prepared(scene)
    return measured.with_size(size) if size < scene.camera.width else measured


# --------------------------------------------------------------------------- the maps
def fit_to(values: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """``values`` resampled to ``shape`` (rows, columns) by the nearest pixel (the case
    may be measured on fewer pixels than the image has)."""
    rows = np.arange(shape[0]) * values.shape[0] // shape[0]
    cols = np.arange(shape[1]) * values.shape[1] // shape[1]
    return values[rows[:, None], cols[None, :]]


def view_scale(shown: ViewMap) -> ColourScale:
    """The colour scale of a view's map."""
    return ColourScale(shown.bottom, shown.top, shown.unit, shown.caption, shown.colours)


def view_rgba(
    view: InstrumentView, scene: Scene, result: Any, shape: tuple[int, int]
) -> tuple[np.ndarray, ColourScale]:
    """The view's picture at the image's ``shape``: the map on its colour scale (grey
    where it has no value), and the scale."""
    shown = view.map_of(scene, result)
    scale = view_scale(shown)
    if not np.isfinite(shown.values).all():
        scale = replace(scale, caption=scale.caption + ", grey: none")
    return colour_mapped(fit_to(shown.values, shape), scale), scale


def view_hover(
    view: InstrumentView, scene: Scene, result: Any, row: int, col: int, shape: tuple[int, int]
) -> str:
    """The map's value at image pixel ``(row, col)`` of an image of ``shape``."""
    shown = view.map_of(scene, result)
    height, width = shown.values.shape[:2]
    return view.hover(shown, row * height // shape[0], col * width // shape[1])


# --------------------------------------------------------------------------- readout
@dataclass(frozen=True)
class InstrumentCase:
    """The latest case an instrument view's station finished: its instrument, the scene
    measured, its result (None before the first, or when the instrument refused the
    scene: ``error`` says why) and the seconds it took."""

    instrument: Instrument | None = None
    scene: Scene | None = None
    result: Any = None
    error: str | None = None
    seconds: float = 0.0


def case_lines(
    offer: InstrumentViews, case: InstrumentCase, computing: bool, size: int
) -> list[str]:
    """The readout of an instrument view: the instrument's numbers ("..." before the
    first result, "-" and the reason on a refusal) and what its station is doing."""
    result = case.result if case.error is None else None
    lines = offer.readout(case.scene, result, "-" if case.error is not None else "...")
    doing = "computing..." if computing else f"{case.seconds:.2f} s"
    lines.append(f"{offer.label} at {size} px: {doing}")
    if case.error is not None:
        lines.append(f"not measured: {case.error}")
    return lines


def first_views(offered: dict[str, OfferedView]) -> list[OfferedView]:
    """Each instrument's first view, in the registry's order."""
    firsts: dict[str, OfferedView] = {}
    for one in offered.values():
        firsts.setdefault(one.instrument.name, one)
    return list(firsts.values())


# --------------------------------------------------------------------------- station
class InstrumentCases:
    """The instrument views' side of the viewer: the ``last`` case its station finished
    (or the refusal of its scene), the ``job`` in flight, and how many cases were
    ``taken`` (a new one changes the picture). One job at a time, never queued up.
    ``table``: the scene file's ``[measure]`` (its settings where it is the instrument's)."""

    def __init__(
        self,
        make_renderer: Callable[[], Renderer] | None = None,
        table: MeasureTable | None = None,
    ) -> None:
        self.last = InstrumentCase()
        self.job: Future | None = None
        self.taken = 0
        self._make_renderer = make_renderer
        self._table = table
        self._station: Station | None = None

    def of(self, offered: OfferedView | None) -> InstrumentCase:
        """The last case of ``offered``'s instrument (empty before its first)."""
        if offered is None or self.last.instrument is not offered.instrument:
            return InstrumentCase()
        return self.last

    def start(self, offered: OfferedView, scene: Scene, size: int) -> None:
        """Measure ``scene`` (its stripes' phase dropped) as ``offered``'s instrument
        does, ``size`` pixels across, unless that instrument's last case was of this
        scene or a job is in flight; a scene it cannot prepare is a refusal."""
        if self.job is not None:
            return
        last = self.of(offered)
        try:
            measured = case_scene(offered.instrument, scene, size)
        except GlshadeError as exc:
            error = " ".join(str(exc).split())
            if last.error != error:
                self.last = InstrumentCase(offered.instrument, error=error)
                self.taken += 1
            return
        if measured == last.scene:
            return
        if self._station is None:
            self._station = Station(self._make_renderer, self._table)
        self.job = self._station.submit(offered, measured)

    def collect(self) -> bool:
        """Take the finished job's case; True when one was taken."""
        if self.job is None or not self.job.done():
            return False
        self.last, self.job = self.job.result(), None
        self.taken += 1
        return True

    def close(self) -> None:
        if self._station is not None:
            self._station.close()
            self._station = None


class Station:
    """Measures instrument views' cases in one thread of its own, with a renderer made
    there on first use (default: its own headless GL context), each through its
    instrument's measurer (its offer's, made once, or :meth:`Instrument.measure`) with
    its settings: the scene file's ``table`` where it is that instrument's, else the
    defaults."""

    def __init__(
        self,
        make_renderer: Callable[[], Renderer] | None = None,
        table: MeasureTable | None = None,
    ) -> None:
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="glshade-instrument")
        self._make_renderer = make_renderer
        self._table = table
        self._renderer: Renderer | None = None
        self._measurers: dict[str, Callable[[Renderer, Scene], Any]] = {}

    def submit(self, offered: OfferedView, scene: Scene) -> Future:
        """Measure ``scene``; the future's result is an :class:`InstrumentCase`."""
        return self._pool.submit(self._case, offered, scene)

    def _case(self, offered: OfferedView, scene: Scene) -> InstrumentCase:
        start = time.perf_counter()
        try:
            result = self._measurer(offered)(self._renderer_made(), scene)
        except GlshadeError as exc:
            return InstrumentCase(offered.instrument, scene, None, " ".join(str(exc).split()))
        return InstrumentCase(offered.instrument, scene, result, None, time.perf_counter() - start)

    def _renderer_made(self) -> Renderer:
        if self._renderer is None:
            if self._make_renderer is not None:
                self._renderer = self._make_renderer()
            else:
                from glshade.gpu.renderer import Renderer

                self._renderer = Renderer()
        return self._renderer

    def _measurer(self, offered: OfferedView) -> Callable[[Renderer, Scene], Any]:
        instrument, name = offered.instrument, offered.instrument.name
        if name not in self._measurers:
            settings = instrument.settings(**(self._table.for_method(name) if self._table else {}))
            make = offered.offer.measurer
            self._measurers[name] = (
                make(settings)
                if make is not None
                else lambda renderer, scene: instrument.measure(renderer, scene, settings)
            )
        return self._measurers[name]

    def close(self) -> None:
        """Wait for the case in flight, then release the renderer in its own thread."""
        self._pool.submit(self._release).result()
        self._pool.shutdown(wait=True)

    def _release(self) -> None:
        release = getattr(self._renderer, "release", None)
        if release is not None:
            release()
        self._renderer = None
        self._measurers.clear()
