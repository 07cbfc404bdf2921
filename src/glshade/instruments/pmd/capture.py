"""A PMD case's capture and decoding: the fringe sequence of a scene shaded in one trace
(:func:`capture`), recorded and decoded like a station (:func:`decode_sequence`), and
which pixels see the screen."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from glshade.components.emitter.fringes.table import (
    DIRECTIONS,
    FringeFrame,
    FringesTable,
)
from glshade.frame import Region
from glshade.instruments.pmd import decode as pmd
from glshade.instruments.pmd.settings import PmdSettings
from glshade.scene import Scene

if TYPE_CHECKING:
    from glshade.instruments.pmd.model import StationModel
    from glshade.rendering import Renderer


# --------------------------------------------------------------------------- capture
@dataclass(frozen=True)
class Capture:
    """One scene's fringe sequence, shaded in one trace: ``radiance`` (F, H, W) of the
    coded ``frames`` in order, ``white`` (H, W) the response to the screen's full scale,
    ``uv`` (H, W, 2) the exact screen points (mm, NaN where none), ``gain`` the exposure
    (recorded units per radiance; 1 without a sensor)."""

    scene: Scene
    frames: tuple[FringeFrame, ...]
    radiance: np.ndarray
    white: np.ndarray
    uv: np.ndarray
    gain: float
    seconds: float

    def recorded(self, seed_offset: int = 0) -> np.ndarray:
        """The sequence as the sensor records it (float32, F × H × W; the radiance itself
        without a sensor): each frame with its own noise, drawn from the sensor's seed
        (plus ``seed_offset``), the scene and the frame shown; the sensor's black level
        kept, as a camera's raw frames keep it."""
        if not self.scene.active.records(self.scene):
            return self.radiance
        out = np.empty_like(self.radiance)
        for index, frame in enumerate(self.frames):
            out[index] = self._developed(frame, self.radiance[index], seed_offset)
        return out

    def recorded_white(self, seed_offset: int = 0) -> np.ndarray:
        """The screen's white as the sensor records it (H × W, exposed as the sequence,
        with its own noise; the radiance without a sensor)."""
        if not self.scene.active.records(self.scene):
            return self.white
        white = self.scene.active.emitter.white(self.scene)
        return self._developed(white, self.white, seed_offset)

    def _developed(self, frame: FringeFrame, radiance: np.ndarray, seed_offset: int) -> np.ndarray:
        scene = self.scene
        base = scene.with_value("camera.exposure", self.gain)
        if seed_offset:
            base = base.with_value("sensor.seed", (scene.sensor.seed + seed_offset) % 2**63)
        shown = scene.active.emitter.showing(base, frame)
        return shown.active.develop(shown, radiance.copy())

    @property
    def black_level(self) -> float:
        """The sensor's black level in recorded units (0 without a sensor): what every
        recorded value holds on top of its signal."""
        records = self.scene.active.records(self.scene)
        return self.scene.sensor.black_level if records else 0.0

    @property
    def peak_response(self) -> float:
        """The noise-free recorded response of the brightest pixel to the screen's white,
        above the black level (recorded units; the radiance without a sensor): the base
        of the validity threshold. The full well fills the range above the black level,
        so a response ``gain · W`` is ``(1 - black) · min(gain · W, 1)`` of full scale."""
        white = self.white[np.isfinite(self.white)]
        peak = float(white.max()) * self.gain if white.size else 0.0
        if not self.scene.active.records(self.scene):
            return peak
        return (1.0 - self.black_level) * min(peak, 1.0)


def capture(renderer: Renderer, scene: Scene) -> Capture:
    """Render ``scene``'s whole coded sequence and its white frame in one trace."""
    start = time.perf_counter()
    emitter = scene.active.emitter
    frames, white = tuple(emitter.sequence(scene)), emitter.white(scene)
    records = scene.active.records(scene)
    stack = renderer.render(scene, ("frames", "uv"), frames=(*frames, white))
    gain = renderer.exposure_gain(scene) if records else 1.0
    layers = stack.output("frames")
    return Capture(
        scene,
        frames,
        layers[:-1],
        layers[-1],
        stack.output("uv").astype(np.float64),
        gain,
        time.perf_counter() - start,
    )


# --------------------------------------------------------------------------- decoding
@dataclass(frozen=True)
class Decoding:
    """A recorded sequence decoded: ``uv`` (H, W, 2) the decoded screen points in mm (NaN
    where a direction is not coded or not valid), ``valid`` (H, W) valid in every coded
    direction, per screen coordinate ``modulation``, ``offset`` and ``wrapped`` (2, K, H,
    W: the first axis in the screen's order (u, v) like ``uv``'s last, whatever order the
    sequence shows them in; NaN for a coordinate the sequence does not code and, where
    ``seen`` was given, for a pixel that sees no screen), ``threshold`` the modulation a
    valid pixel needs (recorded units)."""

    uv: np.ndarray
    valid: np.ndarray
    modulation: np.ndarray
    offset: np.ndarray
    wrapped: np.ndarray
    threshold: float


def threshold_of(coding: FringesTable, peak_response: float, settings: PmdSettings) -> float:
    """The modulation a valid pixel needs (recorded units): ``min_modulation`` where
    given, else ``modulation_share`` of ``amplitude`` times ``peak_response`` (the
    brightest pixel's response to the screen's white above the black level)."""
    if settings.min_modulation is not None:
        return float(settings.min_modulation)
    return float(settings.modulation_share * coding.amplitude * peak_response)


def decode_sequence(
    em: FringesTable,
    recorded: np.ndarray,
    peak_response: float,
    settings: PmdSettings,
    seen: np.ndarray | None = None,
) -> Decoding:
    """Decode every coded direction of a recorded ``(F, H, W)`` sequence of the coding
    ``em`` (``seen``: the pixels that see the screen; the per-direction maps are NaN
    elsewhere)."""
    periods, shifts = len(em.periods), em.shifts
    height, width = recorded.shape[1:]
    uv = np.full((height, width, 2), np.nan)
    valid = np.ones((height, width), bool)
    threshold = threshold_of(em, peak_response, settings)
    # float32 as each direction is decoded: one direction's float64 maps at a time
    shape = (2, periods, height, width)
    modulation, offset, wrapped = (np.full(shape, np.nan, np.float32) for _ in range(3))
    for d, direction in enumerate(em.directions):
        block = recorded[d * periods * shifts : (d + 1) * periods * shifts]
        decoded = pmd.decode(
            block.reshape(periods, shifts, height, width),
            em.codec,
            min_modulation=threshold,
            direction=direction,
        )
        axis = DIRECTIONS.index(direction) ^ 1
        uv[..., axis] = decoded.s_mm - em.half_size[axis]
        valid &= decoded.valid
        modulation[axis], offset[axis], wrapped[axis] = (
            decoded.modulation,
            decoded.offset,
            decoded.wrapped,
        )
        del decoded
    uv[~valid] = np.nan
    if seen is not None:
        for per_direction in (modulation, offset, wrapped):
            per_direction[:, :, ~seen] = np.nan
    return Decoding(uv, valid, modulation, offset, wrapped, threshold)


def coded_axes(coding: FringesTable) -> list[int]:
    """The screen coordinates the sequence codes (0: u, 1: v)."""
    return [DIRECTIONS.index(d) ^ 1 for d in coding.directions]


def failures(decoded_uv: np.ndarray, exact_uv: np.ndarray, model: StationModel) -> np.ndarray:
    """Valid pixels where some coded direction decodes more than half the finest period
    away from the exact map (the unwrapping picked another fringe)."""
    half = model.half_period_mm
    bad = np.zeros(decoded_uv.shape[:2], bool)
    for axis in model.axes:
        with np.errstate(invalid="ignore"):
            bad |= np.abs(decoded_uv[..., axis] - exact_uv[..., axis]) > half
    return bad


def interior(seen: np.ndarray, within: np.ndarray | None = None) -> np.ndarray:
    """The pixels of ``seen`` whose eight neighbours are in it too (``within``: only
    those of its pixels are asked for, False elsewhere: the erosion covers their bounding
    box alone). A pixel on the edge of what sees the screen straddles it: with several
    rays a pixel its exact screen point is the mean of the rays that reach the screen,
    and the least move of the screen's edge across its footprint (a dent's faint tail)
    changes which rays those are and jumps the mean by a share of the footprint. Its move
    is not the dent's."""
    from scipy.ndimage import binary_erosion

    structure = np.ones((3, 3), bool)
    if within is None:
        return binary_erosion(seen, structure=structure, border_value=1)
    out = np.zeros(seen.shape, bool)
    box = Region.of_mask(within)
    if box is None:
        return out
    rows, cols = box.grown(1, *seen.shape).slices
    out[rows, cols] = binary_erosion(seen[rows, cols], structure=structure, border_value=1)
    return out & within
