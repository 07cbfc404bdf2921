"""The viewer's PMD views: what a phase-measuring deflectometry station measures of the
scene (its fringe sequence rendered, recorded and decoded by
:func:`glshade.measure.pmd.measure_pmd_scene`), measured in a thread of its own with a
renderer of its own, and shown as colour maps, with the station's numbers in the
readout. A scene of stripes is measured with the fringe sequence on the same screen
(:func:`glshade.measure.single.as_method`)."""

from __future__ import annotations

import math
import time
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from glshade.app.viewer.colourbar import ColourScale, colour_mapped
from glshade.app.viewer.controls import VIEWS, geometry_key
from glshade.components.emitter.fringes.table import fringes_of
from glshade.errors import GlshadeError
from glshade.measure.pmd import (
    PmdBaseline,
    PmdResult,
    PmdSettings,
    coded_axes,
    measure_pmd_scene,
    pmd_baseline,
    pmd_concerns,
)
from glshade.measure.pmd_files import decoded_only
from glshade.measure.single import as_method
from glshade.scene import Scene

if TYPE_CHECKING:
    from glshade.gpu.renderer import Renderer

#: The PMD views, each a map of the case: the finest period's wrapped phase and its
#: modulation (first coded direction), the decoding error along that direction, and the
#: slope deviation's magnitude.
PMD_VIEWS = tuple(view for view in VIEWS if view.startswith("pmd-"))
#: Pixels across a PMD case is measured on, by default (at most the image's): at 256 px
#: a case takes a fraction of a second, at 512 px one to three seconds on 2 CPU cores.
PMD_SIZE = 256


def pmd_scene(scene: Scene, size: int = PMD_SIZE) -> Scene:
    """The scene the station measures: ``scene`` with the fringes on its screen, its
    stripe phase ignored (the fringes have none), ``size`` pixels across (the same field
    of view) where that is fewer than the image's."""
    measured = as_method(geometry_key(scene), "pmd")
    return measured.with_size(size) if size < scene.camera.width else measured


# --------------------------------------------------------------------------- the maps
def pmd_map(view: str, scene: Scene, result: PmdResult) -> tuple[np.ndarray, ColourScale]:
    """The map ``view`` shows (H, W, float64, NaN where there is none) and its scale."""
    em = fringes_of(scene)
    finest, direction = em.periods[0], em.directions[0]
    shown = coded_axes(scene)[0]  # the first coded direction's layer of the (u, v) maps
    maps = result.maps
    if view == "pmd-phase":
        caption = f"phase, {finest:g} mm fringes along {direction}"
        return decoded_only(maps.wrapped[shown, 0], maps.decoded), ColourScale(
            0.0, 2.0 * math.pi, "rad", caption, "twilight"
        )
    if view == "pmd-modulation":
        values = maps.modulation[shown, 0].astype(np.float64)
        units = "of full scale" if scene.active.records(scene) else "radiance"
        caption = f"modulation ({units}), {finest:g} mm"
        return values, ColourScale(0.0, _top(values), "", caption, "viridis")
    trusted = ~maps.failed
    if view == "pmd-error":
        axis = coded_axes(scene)[0]
        values = 1e3 * maps.error[..., axis]
        caption = f"decoded - exact {'uv'[axis]} on the screen"
        top = _top(np.abs(values[trusted]), 99.5)
        return values, ColourScale(-top, top, "um", caption, "RdBu_r")
    if view == "pmd-slope":
        values = np.hypot(maps.slopes_urad[..., 0], maps.slopes_urad[..., 1]).astype(np.float64)
        return values, ColourScale(0.0, _top(values[trusted]), "urad", "slope deviation", "magma")
    raise GlshadeError(f"view: not a PMD view: {view!r}")


def _top(values: np.ndarray, percentile: float = 100.0) -> float:
    """The scale's top: the largest finite value (or the given percentile), 1 for none."""
    finite = values[np.isfinite(values)]
    top = float(np.percentile(finite, percentile)) if finite.size else 0.0
    return top if top > 0.0 else 1.0


def fit_to(values: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """``values`` resampled to ``shape`` (rows, columns) by the nearest pixel (the PMD
    case may be measured on fewer pixels than the image has)."""
    rows = np.arange(shape[0]) * values.shape[0] // shape[0]
    cols = np.arange(shape[1]) * values.shape[1] // shape[1]
    return values[rows[:, None], cols[None, :]]


def pmd_rgba(
    view: str, scene: Scene, result: PmdResult, shape: tuple[int, int]
) -> tuple[np.ndarray, ColourScale]:
    """The view's picture at the image's ``shape``: the map on its colour scale (grey
    where it has no value), and the scale."""
    values, scale = pmd_map(view, scene, result)
    if not np.isfinite(values).all():
        scale = replace(scale, caption=scale.caption + ", grey: none")
    return colour_mapped(fit_to(values, shape), scale), scale


def pmd_hover(
    view: str, scene: Scene, result: PmdResult, row: int, col: int, shape: tuple[int, int]
) -> str:
    """The map's value at image pixel ``(row, col)`` of an image of ``shape``."""
    values, scale = pmd_map(view, scene, result)
    r = row * values.shape[0] // shape[0]
    c = col * values.shape[1] // shape[1]
    value = values[r, c]
    name = view.removeprefix("pmd-")
    return f"{name}: not decoded" if not np.isfinite(value) else f"{name} {value:.4g} {scale.unit}"


# --------------------------------------------------------------------------- readout
@dataclass(frozen=True)
class PmdReadout:
    """The latest PMD case the station finished: the scene measured, its result (None
    before the first, or when the station refused the scene: ``error`` says why) and
    the seconds it took (the defect-free analysis included when it was redone)."""

    scene: Scene | None = None
    result: PmdResult | None = None
    error: str | None = None
    seconds: float = 0.0


def pmd_readout_lines(r: PmdReadout, computing: bool, size: int) -> list[str]:
    """The readout of a PMD view: the shift, its SNR, the depth against dmax, the
    unwrapping failures, the status and what the station is doing ("..." before the
    first result, "-" and the reason on a refusal; a number the status makes unreadable
    is marked as the paper's are)."""
    res = r.result

    def shown(column: str, text) -> str:
        if res is None:
            return "-" if r.error is not None else "..."
        flag = f" [{res.status}: not measurable]" if pmd_concerns(res.status, column) else ""
        return text(res) + flag

    dmax = "" if r.scene is None else f" (dmax {1e3 * r.scene.defect.dmax:g} um)"
    lines = [
        "PMD shift: " + shown("pmd_shift_mm", lambda x: f"{x.pmd_shift_mm:.4g} mm on the screen"),
        "PMD SNR: " + shown("pmd_snr", _snr),
        "PMD depth: " + shown("pmd_depth_um", lambda x: f"{x.pmd_depth_um:.4g} um{dmax}"),
        "unwrap failures: "
        + shown("", lambda x: f"{x.unwrap_failures} px; valid {x.valid_fraction:.1%}"),
    ]
    if res is None:
        lines.append("status: -" if r.error is not None else "status: ...")
    else:
        reason = f": {res.status_reason}" if res.status_reason else ""
        lines.append(f"status: {res.status}{reason}")
    lines.append(f"PMD at {size} px: " + ("computing..." if computing else f"{r.seconds:.2f} s"))
    if r.error is not None:
        lines.append(f"not measured: {r.error}")
    return lines


def _snr(result: PmdResult) -> str:
    return "inf (no sensor noise)" if result.pmd_noise_mm == 0.0 else f"{result.pmd_snr:.4g}"


# --------------------------------------------------------------------------- station
class PmdStation:
    """Measures PMD cases in one thread of its own, with a renderer (its own headless GL
    context) made there on first use, keeping the defect-free analysis of the last
    geometry (a change of the dent alone renders one sequence, not two)."""

    def __init__(self, settings: PmdSettings | None = None) -> None:
        self.settings = settings or PmdSettings()
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="glshade-pmd")
        self._renderer: Renderer | None = None
        self._baseline: tuple[Scene, PmdBaseline] | None = None

    def submit(self, scene: Scene) -> Future:
        """Measure ``scene``; the future's result is a :class:`PmdReadout`."""
        return self._pool.submit(self._readout, scene)

    def _readout(self, scene: Scene) -> PmdReadout:
        start = time.perf_counter()
        try:
            result = self._measure(scene)
        except GlshadeError as exc:
            return PmdReadout(scene, None, " ".join(str(exc).split()))
        return PmdReadout(scene, result, None, time.perf_counter() - start)

    def _measure(self, scene: Scene) -> PmdResult:
        if self._renderer is None:
            from glshade.gpu.renderer import Renderer

            self._renderer = Renderer()
        renderer, key = self._renderer, scene.without_defect()
        if self._baseline is None or self._baseline[0] != key:
            self._baseline = (key, pmd_baseline(renderer, scene, self.settings))
        return measure_pmd_scene(renderer, scene, self.settings, self._baseline[1])

    def close(self) -> None:
        """Wait for the case in flight, then release the renderer in its own thread."""
        self._pool.submit(self._release).result()
        self._pool.shutdown(wait=True)

    def _release(self) -> None:
        if self._renderer is not None:
            self._renderer.release()
            self._renderer = None
        self._baseline = None
