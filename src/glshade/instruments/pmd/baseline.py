"""A PMD geometry's defect-free analysis, shared by every dent on it: its capture,
decoding, nominal geometry and the noise of two decodes with different seeds
(:class:`PmdBaseline`), and the noise and modulation laws it is checked against."""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from glshade.frame import Region
from glshade.instruments.pmd.capture import Decoding, failures, interior
from glshade.instruments.pmd.model import StationModel
from glshade.instruments.pmd.reconstruct import Nominal, nominal_geometry, slope_map
from glshade.instruments.pmd.settings import PmdSettings
from glshade.instruments.pmd.shots import Shot, shoot

if TYPE_CHECKING:
    from glshade.rendering import Renderer


# --------------------------------------------------------------------------- baseline
@dataclass
class PmdBaseline:
    """The defect-free analysis of one geometry, shared by every dent on it: its
    sequence shot whole (``capture``: traced, recorded once and decoded), the nominal
    geometry, and a second recording with another noise (its twin) decoded where a dent's
    noise is measured (:meth:`twin_over`); ``model`` the station's model of the geometry
    (:class:`~glshade.instruments.pmd.model.StationModel`)."""

    model: StationModel
    settings: PmdSettings
    capture: Shot
    nominal: Nominal
    seconds: dict[str, float] = field(default_factory=dict)
    twins: dict[Region, Decoding] = field(default_factory=dict)
    _slopes: np.ndarray | None = None

    @property
    def slopes(self) -> np.ndarray:
        """The defect-free scene's slope map (H, W, 2; :func:`~glshade.instruments.pmd.
        reconstruct.slope_map`), worked out once: a dent's outside the region its own
        frames cover."""
        if self._slopes is None:
            self._slopes = slope_map(self.model, self.nominal, self.decoding.uv)
        return self._slopes

    @functools.cached_property
    def decode_rms_mm(self) -> float:
        """Root mean square of the defect-free scene's decoded minus exact points over its
        valid pixels that did not fail to unwrap, each coded coordinate counted."""
        base, exact = self.decoding, self.capture.uv
        ok = base.valid & ~failures(base.uv, exact, self.model)
        error = (base.uv - exact)[ok][:, list(self.model.axes)]
        return float(np.sqrt(np.mean(error**2))) if error.size else math.nan

    @property
    def decoding(self) -> Decoding:
        """The whole image's decoding (the first recording)."""
        return self.capture.decoding

    @property
    def noisy(self) -> bool:
        """Does a sensor record the frames (two recordings then differ by its noise)?"""
        return self.model.sensor is not None

    def twin_over(self, renderer: Renderer, window: np.ndarray) -> Decoding | None:
        """The second recording's decoding (another noise) over the bounding box of
        ``window`` grown by a pixel (the noise's pixels are taken off its edge), as
        whole-image arrays (NaN and not valid elsewhere; its uv and validity alone: the
        per-period maps are empty); None without a sensor. Each
        pixel's noise is its own whatever the box (a counter-based generator: the GPU's,
        or NumPy's over the whole image cut to the box), so a box is shot once and kept."""
        if not self.noisy:
            return None
        height, width = window.shape
        found = Region.of_mask(window)
        box = Region(0, 0, 0, 0) if found is None else found.grown(1, height, width)
        twin = self.twins.get(box)
        for held, kept in self.twins.items():
            if twin is None and held.contains(box):
                twin = kept  # recorded over more than asked: the same values there
        if twin is None:
            uv = np.full_like(self.capture.uv, np.nan)
            valid = np.zeros(window.shape, bool)
            if box.rows and box.cols:
                part = shoot(
                    renderer,
                    self.model.truth,
                    self.model.coding,
                    self.settings,
                    region=box,
                    peak=self.capture.peak_response,
                    recording=1,
                ).decoding
                uv[box.slices], valid[box.slices] = part.uv, part.valid
            nothing = np.empty((2, 0, *window.shape), np.float32)  # only uv and valid kept
            twin = Decoding(uv, valid, nothing, nothing, nothing, self.capture.decoding.threshold)
            self.twins[box] = twin
        return twin

    def noise_pixels(self, window: np.ndarray, twin: Decoding | None) -> np.ndarray:
        """The pixels of ``window`` the noise is measured on: valid in both noisy decodes
        (``twin``: :meth:`twin_over` the window), and decoded by neither on another
        fringe than the exact map's (an unwrapping failure is counted, not taken for
        noise). None are without a sensor."""
        if twin is None:
            return np.zeros(window.shape, bool)
        exact = self.capture.uv
        # off the edge of the valid region too (:func:`interior`), as the dent's shift
        both = interior(self.decoding.valid & twin.valid, window)
        both &= ~failures(self.decoding.uv, exact, self.model)
        return both & ~failures(twin.uv, exact, self.model)

    def noise(self, window: np.ndarray, twin: Decoding | None) -> Noise:
        """The decoded coordinate's noise over the pixels of ``window``
        (:meth:`noise_pixels`), each coded coordinate counted: the standard deviation of
        the two noisy decodes' differences over sqrt 2, the largest difference, and the
        prediction from the modulation (all 0 without a sensor)."""
        if twin is None:
            return Noise(0.0, 0.0, 0.0)
        pixels = self.noise_pixels(window, twin)
        diff = (self.decoding.uv - twin.uv)[pixels][:, list(self.model.axes)]
        if not diff.size:
            return Noise(math.nan, math.nan, math.nan)
        return Noise(
            float(np.std(diff) / math.sqrt(2.0)),
            float(np.abs(diff).max()),
            predicted_noise_mm(self.model, self.decoding, pixels),
        )


def pasted(whole: Decoding, part: Decoding, region: Region) -> Decoding:
    """``part`` (``region``'s shape) written into ``whole`` (the image's) in place."""
    rows, cols = region.slices
    whole.uv[rows, cols] = part.uv
    whole.valid[rows, cols] = part.valid
    for name in ("modulation", "offset", "wrapped"):
        getattr(whole, name)[:, :, rows, cols] = getattr(part, name)
    return whole


@dataclass(frozen=True)
class Noise:
    """The decoded coordinate's noise (mm): ``std``, ``floor`` (the largest shift noise
    alone makes) and ``predicted`` (:func:`predicted_noise_mm`)."""

    std: float
    floor: float
    predicted: float


def pmd_baseline(
    renderer: Renderer,
    model: StationModel,
    settings: PmdSettings = PmdSettings(),
    keep_frames: bool = False,
) -> PmdBaseline:
    """The defect-free analysis of the geometry of ``model``
    (:func:`~glshade.instruments.pmd.model.station_model`): the defect-free scene's fringe
    sequence shot whole as it is (``model.truth``), and the nominal geometry the station
    believes (``model.part``); every recorded frame kept where ``keep_frames``."""
    shot = shoot(renderer, model.truth, model.coding, settings, keep_frames=keep_frames)
    start = time.perf_counter()
    nominal = nominal_geometry(renderer, model)
    seconds = {**shot.seconds, "nominal": time.perf_counter() - start}
    return PmdBaseline(model, settings, shot, nominal, seconds)


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
def median_share(axes: tuple[int, ...], share: np.ndarray, region: np.ndarray) -> float:
    """The record's ``modulation``: the median of :func:`modulation_share` over the coded
    coordinates of the dent's region, else (no region) of every pixel that sees the
    screen; NaN where none does."""
    values = share[list(axes)].astype(np.float64)
    where = region if region.any() else np.isfinite(values).all(axis=0)
    picked = values[:, where]
    picked = picked[np.isfinite(picked)]
    return float(np.median(picked)) if picked.size else math.nan
