"""A PMD geometry's defect-free analysis, shared by every dent on it: its capture,
decoding, nominal geometry and the noise of two decodes with different seeds
(:class:`PmdBaseline`), and the noise and modulation laws it is checked against."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from glshade.components.emitter.fringes.table import (
    DIRECTIONS,
    FringesTable,
)
from glshade.instruments.pmd.capture import (
    Capture,
    Decoding,
    capture,
    decode_sequence,
    failures,
    interior,
    released,
    seen_pixels,
)
from glshade.instruments.pmd.model import StationModel
from glshade.instruments.pmd.reconstruct import (
    Nominal,
    nominal_geometry,
)
from glshade.instruments.pmd.settings import PmdSettings
from glshade.metrics.coding_laws import white_fundamental

if TYPE_CHECKING:
    from glshade.rendering import Renderer


# --------------------------------------------------------------------------- baseline
@dataclass
class PmdBaseline:
    """The defect-free analysis of one geometry, shared by every dent on it: its capture,
    decoded from one recording and again from a second with another seed (the noise),
    the nominal geometry, and the prediction of the noise; ``model`` the station's model
    of the geometry (:class:`~glshade.instruments.pmd.model.StationModel`)."""

    model: StationModel
    settings: PmdSettings
    capture: Capture
    decoding: Decoding
    twin: Decoding | None
    nominal: Nominal
    seconds: dict[str, float] = field(default_factory=dict)

    def noise_pixels(self, window: np.ndarray) -> np.ndarray:
        """The pixels of ``window`` the noise is measured on: valid in both noisy decodes,
        and decoded by neither on another fringe than the exact map's (an unwrapping
        failure is counted, not taken for noise). None are without a sensor."""
        if self.twin is None:
            return np.zeros(window.shape, bool)
        exact = self.capture.uv
        # off the edge of the valid region too (:func:`interior`), as the dent's shift
        both = window & interior(self.decoding.valid & self.twin.valid)
        both &= ~failures(self.decoding.uv, exact, self.model)
        return both & ~failures(self.twin.uv, exact, self.model)

    def noise(self, window: np.ndarray) -> Noise:
        """The decoded coordinate's noise over the pixels of ``window``
        (:meth:`noise_pixels`), each coded coordinate counted: the standard deviation of
        the two noisy decodes' differences over sqrt 2, the largest difference, and the
        prediction from the modulation (all 0 without a sensor)."""
        if self.twin is None:
            return Noise(0.0, 0.0, 0.0)
        pixels = self.noise_pixels(window)
        diff = (self.decoding.uv - self.twin.uv)[pixels][:, list(self.model.axes)]
        if not diff.size:
            return Noise(math.nan, math.nan, math.nan)
        return Noise(
            float(np.std(diff) / math.sqrt(2.0)),
            float(np.abs(diff).max()),
            predicted_noise_mm(self.model, self.decoding, pixels),
        )


@dataclass(frozen=True)
class Noise:
    """The decoded coordinate's noise (mm): ``std``, ``floor`` (the largest shift noise
    alone makes) and ``predicted`` (:func:`predicted_noise_mm`)."""

    std: float
    floor: float
    predicted: float


def pmd_baseline(
    renderer: Renderer, model: StationModel, settings: PmdSettings = PmdSettings()
) -> PmdBaseline:
    """The defect-free analysis of the geometry of ``model``
    (:func:`~glshade.instruments.pmd.model.station_model`): the defect-free scene's fringe
    sequence captured as it is (``model.truth``) and decoded, twice where a sensor adds
    noise; the nominal geometry the station believes (``model.part``)."""
    shot = capture(renderer, model.truth)
    start = time.perf_counter()
    seen = seen_pixels(shot.uv)
    coding, peak = model.coding, shot.peak_response
    decoding = decode_sequence(coding, shot.recorded(), peak, settings, seen)
    twin = None
    if model.sensor is not None:
        twin = decode_sequence(coding, shot.recorded(seed_offset=1), peak, settings, seen)
    decode_s = time.perf_counter() - start
    nominal = nominal_geometry(renderer, model)
    return PmdBaseline(
        model,
        settings,
        released(shot),
        decoding,
        twin,
        nominal,
        {"render": shot.seconds, "decode": decode_s},
    )


# --------------------------------------------------------------------------- noise
def predicted_noise_mm(model: StationModel, decoding: Decoding, mask: np.ndarray) -> float:
    """``periods[0] / 2π · sqrt(2 / N) · σ_I / B`` per pixel of ``mask`` (valid ones),
    pooled as the root mean square (what the measured standard deviation estimates):
    ``σ_I`` the sensor's noise at the pixel's mean level ``A`` (recorded units, the black
    level ``b`` in it: the signal ``A - b`` fills ``1 - b`` of full scale at the full well,
    so photon noise ``(1 - b) (A - b) / full_well`` and read noise ``((1 - b) read /
    full_well)²`` in variance, and the quantisation's ``q² / 12``), ``B`` its modulation
    of the finest period, each coded direction counted. 0 without a sensor."""
    sensor, em = model.sensor, model.coding
    if sensor is None or sensor.full_well_e is None:
        return 0.0
    full_well, black = sensor.full_well_e, sensor.black_level
    q = 1.0 / sensor.full_scale_dn
    scale = em.periods[0] / (2.0 * math.pi)
    variances = []
    for axis in model.axes:
        level = decoding.offset[axis, 0][mask].astype(np.float64)
        modulation = decoding.modulation[axis, 0][mask].astype(np.float64)
        sigma2 = (
            (1.0 - black) * np.maximum(level - black, 0.0) / full_well
            + ((1.0 - black) * sensor.read_noise_e / full_well) ** 2
            + q * q / 12.0
        )
        variances.append(scale**2 * (2.0 / em.shifts) * sigma2 / modulation**2)
    pooled = np.concatenate(variances)
    return float(math.sqrt(pooled.mean())) if pooled.size else math.nan


# --------------------------------------------------------------------------- modulation
def modulation_share(em: FringesTable, shot: Capture) -> np.ndarray:
    """Per screen coordinate (u, v) and pixel (2, H, W, float32), the finest period's
    modulation share of the noise-free radiance, ``B / (b_1 W)``: ``B`` the pixel's
    modulation of the finest fringes, ``W`` its own response to the screen's white, and
    ``b_1`` the fundamental of the fringe the screen displays over the white it displays
    (:func:`displayed_fundamental`). What the finish, the lens and the pixel's footprint
    leave of the fringe: 1 for a sharp mirror (within the screen's grey levels' rounding,
    ±0.5 % at 256 levels), less where they average it out; an optical property, before
    the sensor. NaN for a coordinate not coded and for a pixel that sees no screen."""
    fundamental = displayed_fundamental(em)
    white = shot.white.astype(np.float64)
    seen = seen_pixels(shot.uv) & np.isfinite(white) & (white > 0.0)
    share = np.full((2, *white.shape), np.nan, np.float32)
    steps = em.codec.shifts_rad
    for d, direction in enumerate(em.directions):
        first = d * len(em.periods) * em.shifts
        finest = shot.radiance[first : first + em.shifts].astype(np.float64)
        sine = np.tensordot(np.sin(steps), finest, axes=1)
        cosine = np.tensordot(np.cos(steps), finest, axes=1)
        modulation = (2.0 / em.shifts) * np.hypot(sine, cosine)
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = modulation / (fundamental * white)
        share[DIRECTIONS.index(direction) ^ 1] = np.where(seen, ratio, np.nan)
    return share


def displayed_fundamental(em: FringesTable) -> float:
    """``b_1`` of the fringe the screen displays, ``displayed(offset + amplitude cos θ)``
    (its grey levels, response, black level and ambient light included), over the white
    it displays, ``displayed(1)``: a sharp mirror's modulation per unit of its response to
    the white (:func:`~glshade.metrics.coding_laws.white_fundamental`)."""
    return white_fundamental(em)


def median_share(axes: tuple[int, ...], share: np.ndarray, region: np.ndarray) -> float:
    """The record's ``modulation``: the median of :func:`modulation_share` over the coded
    coordinates of the dent's region, else (no region) of every pixel that sees the
    screen; NaN where none does."""
    values = share[list(axes)].astype(np.float64)
    where = region if region.any() else np.isfinite(values).all(axis=0)
    picked = values[:, where]
    picked = picked[np.isfinite(picked)]
    return float(np.median(picked)) if picked.size else math.nan
