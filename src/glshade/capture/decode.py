"""A capture decoded by glshade's own decoder (:func:`glshade.instruments.pmd.decode.decode`):
screen points in mm, the fit's residual, the noise it implies and the unwrapping's margin
(docs/captures.md)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from glshade.capture.model import Capture
from glshade.components.emitter.fringes.codec import axis_of
from glshade.instruments.pmd import decode as pmd


@dataclass(frozen=True)
class CaptureDecoding:
    """A capture decoded. Per screen axis (u, v) on the first axis of the maps:
    ``uv`` (H, W, 2) mm from the screen's centre along +u, +v (NaN where not coded or not
    valid); ``fraction`` (H, W, 2) the same as a share of the screen, 0 at its -half_size
    edge, 1 at +half_size; ``modulation``, ``offset`` (2, K, H, W) per period finest first;
    ``residual`` (2, H, W) the rms over periods and shifts of the frames less their N-step
    fit; ``noise_mm`` (2, H, W) the coordinate's noise the residual implies;
    ``margin`` (2, H, W) the least unwrapping margin (turns of the finer period, 0.5 at
    best, 0 on the edge of a wrong fringe); ``valid`` (H, W) valid in every coded
    direction; ``threshold`` the modulation a valid pixel needs; ``normalised`` whether
    the frames were divided by white - black."""

    uv: np.ndarray
    fraction: np.ndarray
    modulation: np.ndarray
    offset: np.ndarray
    residual: np.ndarray
    noise_mm: np.ndarray
    margin: np.ndarray
    valid: np.ndarray
    threshold: float
    normalised: bool

    @property
    def valid_share(self) -> float:
        """The share of the pixels valid."""
        return float(self.valid.mean())


def prepared(capture: Capture) -> tuple[np.ndarray, float, bool]:
    """The frames to decode, the peak response the threshold is based on, and whether
    they were normalised: ``(I - black) / (white - black)`` where both references exist
    (response 1; NaN where white is not above black), else as recorded with the capture's
    peak response (or, without one, the white's largest value above black, or the
    largest recorded value)."""
    frames = np.asarray(capture.frames, np.float64)
    if capture.black is not None and capture.white is not None:
        span = np.asarray(capture.white, np.float64) - capture.black
        with np.errstate(invalid="ignore", divide="ignore"):
            scale = np.where(span > 0, 1.0 / span, np.nan)
        return (frames - capture.black) * scale, 1.0, True
    if capture.peak_response is not None:
        return frames, float(capture.peak_response), False
    if capture.white is not None:
        base = 0.0 if capture.black is None else float(np.nanmedian(capture.black))
        return frames, float(np.nanmax(capture.white)) - base, False
    return frames, float(np.nanmax(frames)), False


def decode_capture(capture: Capture, min_modulation_share: float = 0.1) -> CaptureDecoding:
    """Decode every coded direction of ``capture``: valid where every period's modulation
    is at least ``min_modulation_share`` x amplitude x the peak response."""
    coding = capture.coding
    frames, peak, normalised = prepared(capture)
    blocks = coding.glshade_order(frames)
    height, width = capture.shape
    periods = len(coding.periods)
    uv = np.full((height, width, 2), np.nan)
    fraction = np.full((height, width, 2), np.nan)
    shape = (2, periods, height, width)
    modulation, offset = np.full(shape, np.nan), np.full(shape, np.nan)
    residual, noise, margin = (np.full((2, height, width), np.nan) for _ in range(3))
    valid = np.ones((height, width), bool)
    amplitude = 0.5 if coding.amplitude is None else coding.amplitude
    threshold = float(min_modulation_share * amplitude * peak)
    for direction in coding.directions:
        codec = coding.codec(direction)
        block = blocks[direction]
        decoded = pmd.decode(block, codec, min_modulation=threshold, direction=direction)
        axis = axis_of(direction)
        size = coding.screen_size_mm[axis]
        s = decoded.s_mm
        if coding.origin[axis] == "high":
            s = size - s
        uv[..., axis] = s - 0.5 * size
        fraction[..., axis] = s / size
        valid &= decoded.valid
        modulation[axis], offset[axis] = decoded.modulation, decoded.offset
        residual[axis] = _residual(block, decoded, codec.shifts_rad)
        sigma = residual[axis] * _dof_factor(codec.shifts)
        with np.errstate(invalid="ignore", divide="ignore"):
            noise[axis] = pmd.predicted_noise_mm(codec, 1.0, 1.0) * sigma / decoded.modulation[0]
        margin[axis] = _margin(block, decoded, codec, threshold, direction)
    uv[~valid] = np.nan
    fraction[~valid] = np.nan
    return CaptureDecoding(
        uv, fraction, modulation, offset, residual, noise, margin, valid, threshold, normalised
    )


def _residual(block: np.ndarray, decoded: pmd.Decoded, steps: np.ndarray) -> np.ndarray:
    """The rms over periods and shifts of ``I - (A + B cos(φ - δ_n))``."""
    total = np.zeros(block.shape[2:])
    for n, step in enumerate(steps):
        fit = decoded.offset + decoded.modulation * np.cos(decoded.wrapped - step)
        total += ((block[:, n] - fit) ** 2).sum(axis=0)
    return np.sqrt(total / (block.shape[0] * block.shape[1]))


def _dof_factor(shifts: int) -> float:
    """The noise σ over the residual rms of an N-step fit (3 parameters: N - 3 degrees
    of freedom left; N = 3 fits exactly and the residual says nothing: NaN)."""
    return math.sqrt(shifts / (shifts - 3)) if shifts > 3 else math.nan


def _margin(
    block: np.ndarray,
    decoded: pmd.Decoded,
    codec: pmd.FringeCodec,
    threshold: float,
    direction: str,
) -> np.ndarray:
    """The least unwrapping margin over the steps: at step ``k`` the coarser estimate
    ``s_{k+1}`` (glshade's decoder on the periods from ``k+1`` on) in turns of period
    ``k`` less the wrapped phase, its distance to the nearest half turn."""
    from dataclasses import replace

    periods = codec.periods_mm
    least = np.full(block.shape[2:], 0.5)
    for k in range(len(periods) - 1):
        tail = replace(codec, periods_mm=periods[k + 1 :])
        coarse = pmd.decode(block[k + 1 :], tail, min_modulation=threshold, direction=direction)
        turns = coarse.s_mm / periods[k] - decoded.wrapped[k] / (2.0 * np.pi)
        least = np.fmin(least, 0.5 - np.abs(turns - np.round(turns)))
    least[~decoded.valid] = np.nan
    return least
