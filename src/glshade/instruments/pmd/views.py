"""What phase measuring offers the interactive viewer (``glshade view``): four maps of a
measured case, the finest period's wrapped phase and its modulation (first coded
direction), the decoding error along that direction and the slope deviation's magnitude,
and the station's numbers for the readout. NumPy only: the viewer colours and draws them.

The viewer measures a case at :data:`PMD_SIZE` pixels across with one renderer, keeping
the defect-free analysis of the last geometry (:class:`KeptBaseline`: a change of the
dent alone renders one sequence, not two)."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from glshade.components.emitter.fringes.table import fringes_of
from glshade.instruments.base import InstrumentView, InstrumentViews, ViewMap
from glshade.instruments.pmd.baseline import PmdBaseline, pmd_baseline
from glshade.instruments.pmd.capture import coded_axes
from glshade.instruments.pmd.files import decoded_only
from glshade.instruments.pmd.model import defect_free, station_model
from glshade.instruments.pmd.settings import PmdSettings
from glshade.instruments.pmd.station import PmdResult, measure_pmd_scene
from glshade.instruments.pmd.status import pmd_concerns
from glshade.scene import Scene

if TYPE_CHECKING:
    from glshade.rendering import Renderer

#: Pixels across a case is measured on, by default (at most the image's): at 256 px a
#: case takes a fraction of a second, at 512 px one to three seconds on 2 CPU cores.
PMD_SIZE = 256


# --------------------------------------------------------------------------- the maps
def phase_map(scene: Scene, result: PmdResult) -> ViewMap:
    """The finest period's wrapped phase, where the pixel was decoded."""
    em = fringes_of(scene)
    shown, maps = coded_axes(fringes_of(scene))[0], result.maps  # the first coded direction's layer
    values = decoded_only(maps.wrapped[shown, 0], maps.decoded)
    caption = f"phase, {em.periods[0]:g} mm fringes along {em.directions[0]}"
    return ViewMap(values, 0.0, 2.0 * math.pi, "rad", caption, "twilight")


def modulation_map(scene: Scene, result: PmdResult) -> ViewMap:
    """The finest period's modulation (a share of full scale where the sensor records)."""
    shown = coded_axes(fringes_of(scene))[0]
    values = result.maps.modulation[shown, 0].astype(np.float64)
    units = "of full scale" if scene.active.records(scene) else "radiance"
    caption = f"modulation ({units}), {fringes_of(scene).periods[0]:g} mm"
    return ViewMap(values, 0.0, _top(values), "", caption, "viridis")


def error_map(scene: Scene, result: PmdResult) -> ViewMap:
    """Decoded minus exact screen point along the first coded direction (µm)."""
    axis, maps = coded_axes(fringes_of(scene))[0], result.maps
    values = 1e3 * maps.error[..., axis]
    top = _top(np.abs(values[~maps.failed]), 99.5)
    caption = f"decoded - exact {'uv'[axis]} on the screen"
    return ViewMap(values, -top, top, "um", caption, "RdBu_r")


def slope_map(scene: Scene, result: PmdResult) -> ViewMap:
    """The slope deviation's magnitude (µrad)."""
    slopes = result.maps.slopes_urad
    values = np.hypot(slopes[..., 0], slopes[..., 1]).astype(np.float64)
    top = _top(values[~result.maps.failed])
    return ViewMap(values, 0.0, top, "urad", "slope deviation", "magma")


def _top(values: np.ndarray, percentile: float = 100.0) -> float:
    """The scale's top: the largest finite value (or the given percentile), 1 for none."""
    finite = values[np.isfinite(values)]
    top = float(np.percentile(finite, percentile)) if finite.size else 0.0
    return top if top > 0.0 else 1.0


# --------------------------------------------------------------------------- readout
def readout_lines(scene: Scene | None, result: PmdResult | None, missing: str) -> list[str]:
    """The station's numbers: the shift, its SNR, the depth against dmax, the unwrapping
    failures and the status (a number the status makes unreadable is marked as the
    paper's are); ``missing`` for each while there is no result."""

    def shown(column: str, text: Callable[[PmdResult], str]) -> str:
        if result is None:
            return missing
        flag = f" [{result.status}: not measurable]" if pmd_concerns(result.status, column) else ""
        return text(result) + flag

    dmax = "" if scene is None else f" (dmax {1e3 * scene.defect.dmax:g} um)"
    lines = [
        "PMD shift: " + shown("pmd_shift_mm", lambda x: f"{x.pmd_shift_mm:.4g} mm on the screen"),
        "PMD SNR: " + shown("pmd_snr", _snr),
        "PMD depth: " + shown("pmd_depth_um", lambda x: f"{x.pmd_depth_um:.4g} um{dmax}"),
        "unwrap failures: "
        + shown("", lambda x: f"{x.unwrap_failures} px; valid {x.valid_fraction:.1%}"),
    ]
    if result is None:
        lines.append(f"status: {missing}")
    else:
        reason = f": {result.status_reason}" if result.status_reason else ""
        lines.append(f"status: {result.status}{reason}")
    return lines


def _snr(result: PmdResult) -> str:
    return "inf (no sensor noise)" if result.pmd_noise_mm == 0.0 else f"{result.pmd_snr:.4g}"


# --------------------------------------------------------------------------- measuring
class KeptBaseline:
    """Measures the viewer's cases, keeping the defect-free analysis of the last geometry
    (a change of the dent alone renders one sequence, not two)."""

    def __init__(self, settings: Any) -> None:
        self.settings: PmdSettings = settings
        self._baseline: tuple[Scene, PmdBaseline] | None = None

    def __call__(self, renderer: Renderer, scene: Scene) -> PmdResult:
        key = defect_free(scene)
        if self._baseline is None or self._baseline[0] != key:
            self._baseline = (key, pmd_baseline(renderer, station_model(scene), self.settings))
        return measure_pmd_scene(renderer, scene, self.settings, self._baseline[1])


def pmd_views() -> InstrumentViews:
    """Phase measuring's views: ``pmd-phase``, ``pmd-modulation``, ``pmd-error`` and
    ``pmd-slope``."""
    maps = (
        ("phase", phase_map),
        ("modulation", modulation_map),
        ("error", error_map),
        ("slope", slope_map),
    )
    views = tuple(InstrumentView(f"pmd-{label}", label, of, "not decoded") for label, of in maps)
    return InstrumentViews("PMD", views, readout_lines, PMD_SIZE, KeptBaseline)
