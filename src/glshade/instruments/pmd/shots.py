"""A scene's fringe sequence traced, recorded and decoded over a region of the image
(:func:`shoot`), on the GPU where the renderer can (:mod:`glshade.gpu.sequence`: only the
decoded maps cross to the host), else in NumPy (the reference: every frame read back,
developed by the sensor's NumPy model and decoded by :func:`decode_sequence`).

Both paths give a :class:`Shot` of the region's shape, decoded with one codec: the GPU's
maps are finished on the host by the NumPy decoder's own last steps
(:func:`~glshade.instruments.pmd.decode.coarsest_coordinate`,
:func:`~glshade.instruments.pmd.decode.unwrap_step`). Their noise differs in its draws (a
counter-based generator on the GPU, NumPy's on the host), not in its law.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from glshade.components.emitter.fringes.table import DIRECTIONS, FringesTable
from glshade.frame import Region
from glshade.instruments.pmd import decode as pmd
from glshade.instruments.pmd.capture import (
    Decoding,
    capture,
    decode_sequence,
    threshold_of,
)
from glshade.instruments.pmd.settings import PmdSettings
from glshade.metrics.coding_laws import white_fundamental
from glshade.scene import Scene

if TYPE_CHECKING:
    from glshade.gpu.sequence import DecodePlan, DirectionMaps
    from glshade.rendering import Renderer


@dataclass(frozen=True)
class Shot:
    """One scene's sequence over ``region`` (every array of its shape): ``uv`` (rows,
    cols, 2) the exact screen points (mm, NaN where none), ``white`` the radiance of the
    screen's white, ``gain`` the exposure (1 without a sensor), ``black_level`` (recorded
    units; 0 without a sensor), ``peak_response`` the brightest pixel's noise-free
    response to the white above the black level (the validity threshold's base: the
    image's own where the shot was taken whole, else the one it was given),
    ``decoding``, ``share`` (2, rows, cols: :func:`modulation_share`), ``first`` and
    ``recorded_white`` the first frame and the white as recorded, ``recorded`` every
    recorded frame (F, rows, cols) where asked for, else None."""

    region: Region
    uv: np.ndarray
    white: np.ndarray
    gain: float
    black_level: float
    peak_response: float
    decoding: Decoding
    share: np.ndarray
    first: np.ndarray
    recorded_white: np.ndarray
    recorded: np.ndarray | None
    seconds: dict[str, float] = field(default_factory=dict)


def on_gpu(renderer: Renderer, scene: Scene) -> bool:
    """Can ``renderer`` trace, record and decode ``scene``'s sequence on the GPU (a GL
    renderer with compute shaders and fp64, and a sensor with GPU recording where one
    records)?"""
    from glshade.gpu.renderer import Renderer as GlRenderer
    from glshade.gpu.sequence import supports_sequence_passes

    if not isinstance(renderer, GlRenderer) or not supports_sequence_passes(renderer.context):
        return False
    return not scene.active.records(scene) or bool(scene.active.sensor.record_glsl(scene))


def peak_of(white: np.ndarray, gain: float, scene: Scene) -> float:
    """The noise-free recorded response of the brightest pixel of ``white`` above the
    black level (:attr:`Capture.peak_response <glshade.instruments.pmd.capture.Capture.
    peak_response>`)."""
    values = white[np.isfinite(white)]
    peak = float(values.max()) * gain if values.size else 0.0
    if not scene.active.records(scene):
        return peak
    return (1.0 - scene.sensor.black_level) * min(peak, 1.0)


def shoot(
    renderer: Renderer,
    scene: Scene,
    coding: FringesTable,
    settings: PmdSettings,
    *,
    region: Region | None = None,
    peak: float | None = None,
    recording: int = 0,
    keep_frames: bool = False,
    gpu: bool | None = None,
) -> Shot:
    """``scene``'s sequence over ``region`` (None: the whole image), recorded for the
    ``recording``-th time (another noise), decoded with ``coding`` against ``peak`` (None:
    the shot's own: it must then be whole); every frame kept where ``keep_frames``.
    ``gpu``: the GPU path (default: where :func:`on_gpu`)."""
    height, width = scene.camera.height, scene.camera.width
    area = region or Region(0, 0, height, width)
    if peak is None and (area.rows, area.cols) != (height, width):
        raise ValueError("shoot: a region needs the peak response of the whole image")
    asked = _Asked(coding, settings, area, peak, recording, keep_frames)
    if gpu if gpu is not None else on_gpu(renderer, scene):
        return _shoot_gpu(renderer, scene, asked)
    return _shoot_numpy(renderer, scene, asked)


@dataclass(frozen=True)
class _Asked:
    """What a shot is asked for (:func:`shoot`'s arguments, its region worked out)."""

    coding: FringesTable
    settings: PmdSettings
    area: Region
    peak: float | None
    recording: int
    keep_frames: bool


# --------------------------------------------------------------------------- NumPy
def _shoot_numpy(renderer: Renderer, scene: Scene, asked: _Asked) -> Shot:
    """The reference: the whole image rendered and read back, developed by the sensor's
    NumPy model, decoded by :func:`decode_sequence`, then cut to ``area``."""
    coding, area, recording = asked.coding, asked.area, asked.recording
    shot = capture(renderer, scene)
    start = time.perf_counter()
    peak = shot.peak_response if asked.peak is None else asked.peak
    cut = area.slices
    recorded = shot.recorded(seed_offset=recording)[:, cut[0], cut[1]]
    uv = shot.uv[cut]
    seen = np.all(np.isfinite(uv), axis=-1)
    decoding = decode_sequence(coding, recorded, peak, asked.settings, seen)
    share = modulation_share(coding, shot.radiance[:, cut[0], cut[1]], shot.white[cut], uv)
    white = shot.recorded_white(seed_offset=recording)[cut]
    return Shot(
        area,
        uv,
        shot.white[cut].copy(),
        shot.gain,
        shot.black_level,
        peak,
        decoding,
        share,
        recorded[0].copy(),
        white.copy(),
        recorded if asked.keep_frames else None,
        {"render": shot.seconds, "decode": time.perf_counter() - start},
    )


# --------------------------------------------------------------------------- GPU
def _shoot_gpu(renderer: Renderer, scene: Scene, asked: _Asked) -> Shot:
    """Traced over ``area``, recorded and decoded where it was traced; the maps, the
    first frame and the white come back (every frame where ``keep_frames``)."""
    from glshade.gpu.renderer import Renderer as GlRenderer

    assert isinstance(renderer, GlRenderer)
    coding, area, keep_frames = asked.coding, asked.area, asked.keep_frames
    start = time.perf_counter()
    emitter = scene.active.emitter
    frames = (*emitter.sequence(scene), emitter.white(scene))
    records = scene.active.records(scene)
    gain = renderer.exposure_gain(scene) if records else 1.0  # (it may draw: first)
    traced, stack = renderer.trace_sequence(scene, frames, area)
    passes = renderer.sequence_passes()
    white = passes.read(stack, area, [len(frames) - 1])[0].copy()
    render_s = time.perf_counter() - start
    start = time.perf_counter()
    peak = peak_of(white, gain, scene) if asked.peak is None else asked.peak
    uv = traced.output("uv").astype(np.float64)
    seen = np.all(np.isfinite(uv), axis=-1)
    recorded = stack
    if records:
        sensor = scene.active.sensor
        exposed = scene.with_value("camera.exposure", gain)
        recorded = passes.record(
            stack,
            sensor,
            sensor.record_glsl(scene),
            sensor.record_uniforms(exposed, gain),
            sensor.frame_keys(scene, frames, asked.recording),
            area,
        )
    threshold = threshold_of(coding, peak, asked.settings)
    maps = passes.decode(recorded, plan_of(coding, threshold), area)
    decoding = finished(coding, maps, threshold, seen)
    if records:  # the noise-free radiance's own finest modulation: one more pass
        maps = passes.decode(stack, plan_of(coding, 0.0, finest_only=True), area)
    share = _share_of(coding, _finest_modulation(coding, maps, white.shape), white, seen)
    wanted = list(range(len(frames))) if keep_frames else [0, len(frames) - 1]
    layers = passes.read(recorded, area, wanted)
    return Shot(
        area,
        uv,
        white,
        gain,
        scene.sensor.black_level if records else 0.0,
        peak,
        decoding,
        share,
        layers[0].copy(),
        layers[-1].copy(),
        layers[:-1] if keep_frames else None,
        {"render": render_s, "decode": time.perf_counter() - start},
    )


def plan_of(coding: FringesTable, threshold: float, finest_only: bool = False) -> DecodePlan:
    """The decode pass's plan of ``coding`` (its directions in the order shown;
    ``finest_only``: the finest period of each alone)."""
    from glshade.gpu.sequence import DecodePlan

    periods, shifts = len(coding.periods), coding.shifts
    codec = coding.codec
    used = codec.periods_mm[:1] if finest_only else codec.periods_mm
    return DecodePlan(
        first_layers=tuple(d * periods * shifts for d in range(len(coding.directions))),
        extents_mm=tuple(codec.extent_mm(d) for d in coding.directions),
        periods_mm=tuple(float(p) for p in used),
        steps_rad=tuple(float(s) for s in codec.shifts_rad),
        threshold=threshold,
    )


def finished(
    coding: FringesTable,
    maps: list[DirectionMaps],
    threshold: float,
    seen: np.ndarray | None = None,
) -> Decoding:
    """A :class:`Decoding` from the decode pass's maps of each direction: the finest
    period's phase from its sums and the last unwrapping step, in float64 (the NumPy
    decoder's own steps); per-direction maps NaN where ``seen`` is False."""
    periods = np.asarray(coding.codec.periods_mm, np.float64)
    rows, cols = maps[0].valid.shape
    uv = np.full((rows, cols, 2), np.nan)
    valid = np.ones((rows, cols), bool)
    shape = (2, len(periods), rows, cols)
    modulation, offset, wrapped = (np.full(shape, np.nan, np.float32) for _ in range(3))
    for direction, found in zip(coding.directions, maps, strict=True):
        phase = np.mod(
            np.arctan2(found.sine, found.cosine),
            2.0 * np.pi,
        )
        if len(periods) == 1:
            s = pmd.coarsest_coordinate(phase, periods[0], coding.codec.extent_mm(direction))
        else:
            s = pmd.unwrap_step(found.coarse.astype(np.float64), phase, periods[0])
        axis = DIRECTIONS.index(direction) ^ 1
        uv[..., axis] = np.where(found.valid, s, np.nan) - coding.half_size[axis]
        valid &= found.valid
        modulation[axis], offset[axis] = found.modulation, found.offset
        wrapped[axis] = found.wrapped
        wrapped[axis, 0] = phase
    uv[~valid] = np.nan
    if seen is not None:
        for per_direction in (modulation, offset, wrapped):
            per_direction[:, :, ~seen] = np.nan
    return Decoding(uv, valid, modulation, offset, wrapped, threshold)


def _finest_modulation(
    coding: FringesTable, maps: list[DirectionMaps], shape: tuple[int, ...]
) -> np.ndarray:
    """The decode pass's finest modulation per screen coordinate (2, rows, cols; NaN for
    one not coded)."""
    finest = np.full((2, *shape), np.nan)
    for direction, found in zip(coding.directions, maps, strict=True):
        finest[DIRECTIONS.index(direction) ^ 1] = found.modulation[0]
    return finest


# --------------------------------------------------------------------------- modulation
def modulation_share(
    coding: FringesTable, radiance: np.ndarray, white: np.ndarray, uv: np.ndarray
) -> np.ndarray:
    """Per screen coordinate (u, v) and pixel (2, H, W, float32), the finest period's
    modulation share of the noise-free ``radiance`` (F, H, W), ``B / (b_1 W)``: ``B`` the
    pixel's modulation of the finest fringes, ``W`` its own response to the screen's
    ``white``, and ``b_1`` the fundamental of the fringe the screen displays over the
    white it displays (:func:`~glshade.metrics.coding_laws.white_fundamental`). What the
    finish, the lens and the pixel's footprint leave of the fringe: 1 for a sharp mirror
    (within the screen's grey levels' rounding, ±0.5 % at 256 levels), less where they
    average it out; an optical property, before the sensor. NaN for a coordinate not
    coded and for a pixel that sees no screen (``uv`` not finite)."""
    finest = np.full((2, *white.shape), np.nan)
    steps = coding.codec.shifts_rad
    for d, direction in enumerate(coding.directions):
        first = d * len(coding.periods) * coding.shifts
        block = radiance[first : first + coding.shifts].astype(np.float64)
        sine = np.tensordot(np.sin(steps), block, axes=1)
        cosine = np.tensordot(np.cos(steps), block, axes=1)
        finest[DIRECTIONS.index(direction) ^ 1] = (2.0 / coding.shifts) * np.hypot(sine, cosine)
    return _share_of(coding, finest, white, np.all(np.isfinite(uv), axis=-1))


def _share_of(
    coding: FringesTable, finest: np.ndarray, white: np.ndarray, seen: np.ndarray
) -> np.ndarray:
    white = white.astype(np.float64)
    lit = seen & np.isfinite(white) & (white > 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = finest / (white_fundamental(coding) * white)
    return np.where(lit, ratio, np.nan).astype(np.float32)
