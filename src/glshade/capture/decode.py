"""A capture decoded by glshade's own decoder (:func:`glshade.instruments.pmd.decode.decode`):
the display response undone, black and white normalised, per pixel and period the
modulation, offset, validity and fit residual; the screen points in mm and as screen
fractions, the noise the residual implies (and the noise a known camera predicts), the
unwrapping's margin; the lit mask and its largest region (docs/captures.md)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from glshade.capture.masks import largest_region, lit_mask, lit_threshold
from glshade.capture.model import Capture
from glshade.capture.noise import CameraNoise
from glshade.capture.response import Response
from glshade.components.emitter.fringes.codec import axis_of
from glshade.instruments.pmd import decode as pmd

#: How a pixel's coordinate is decoded: from every period (each modulation at least the
#: threshold: the simulator's own rule); from the finest period from which on every one
#: is sound (a blurred finest fringe costs precision, not the pixel); or per period: from
#: the finest period whose coarser periods are sound and unwrap it unambiguously, its own
#: modulation above a lower floor (a blurred finest fringe costs neither).
RULES = ("all", "fallback", "periods")
#: The "periods" rule: the finest period used needs this share of the threshold (a
#: blurred fringe still gives a phase), and every unwrapping step from it on at least
#: this margin (turns of the finer period; 0.5 dead on): a coarser estimate a quarter
#: of a fringe or more from the finer phase's is ambiguous.
FLOOR_SHARE, MIN_MARGIN_TURNS = 0.5, 0.25


@dataclass(frozen=True)
class DecodeSettings:
    """``min_modulation_share`` of amplitude x the peak response a period's modulation
    needs; ``rule`` (:data:`RULES`); ``response`` the display response (None: linear);
    ``noise`` the camera's, for the predicted noise (None: the capture's scene's sensor,
    if any); ``mask`` "region" (the lit pixels' largest region, where black and white
    exist), "lit" (every lit pixel) or "all" (no mask)."""

    min_modulation_share: float = 0.1
    rule: str = "all"
    response: Response | None = None
    noise: CameraNoise | None = None
    mask: str = "region"


@dataclass(frozen=True)
class CaptureDecoding:
    """A capture decoded. Per screen axis (u, v) on the first axis of the maps, periods
    finest first on the second: ``uv`` (H, W, 2) mm from the screen's centre along +u, +v
    (NaN where not coded or not valid); ``fraction`` (H, W, 2) the same as a share of
    the screen, 0 at its -half_size edge; ``modulation``, ``offset`` (2, K, H, W);
    ``period_valid`` (2, K, H, W) each period's modulation at least ``threshold``;
    ``finest_used`` (2, H, W) the finest period the coordinate comes from (-1: none);
    ``residual`` (2, H, W) and ``period_residual`` (2, K, H, W) the rms of the frames
    less their N-step fit; ``noise_mm`` (2, H, W) the coordinate's noise the residual
    implies, ``predicted_noise_mm`` the camera's noise model's (None: unknown);
    ``margin`` (2, H, W) the least unwrapping margin in turns of the finer period (0.5
    at best); ``lit``, ``region`` (H, W) or None; ``valid`` (H, W) valid in every coded
    direction and inside the mask; ``threshold`` the modulation a period needs;
    ``normalised`` whether black and white normalised the frames; ``response`` its label
    ("linear" without one); ``peak`` the screen's white above black in the decoded
    frames' unit (modulation, offset, residual and ``threshold`` are in it: 1 for
    normalised frames, the display maximum through a SOFAST record); ``lit_threshold``
    the white - black the lit mask needs (recorded units; None without a mask)."""

    uv: np.ndarray
    fraction: np.ndarray
    modulation: np.ndarray
    offset: np.ndarray
    period_valid: np.ndarray
    finest_used: np.ndarray
    residual: np.ndarray
    period_residual: np.ndarray
    noise_mm: np.ndarray
    predicted_noise_mm: np.ndarray | None
    margin: np.ndarray
    lit: np.ndarray | None
    region: np.ndarray | None
    valid: np.ndarray
    threshold: float
    normalised: bool
    response: str
    peak: float = 1.0
    lit_threshold: float | None = None

    @property
    def valid_share(self) -> float:
        """The share of the pixels valid."""
        return float(self.valid.mean())

    @classmethod
    def empty(cls, height: int, width: int, periods: int) -> CaptureDecoding:
        """Every map NaN (``finest_used`` -1, nothing valid), to be filled in place one
        screen axis at a time."""
        per_axis, per_period = (2, height, width), (2, periods, height, width)
        return cls(
            uv=np.full((height, width, 2), np.nan),
            fraction=np.full((height, width, 2), np.nan),
            modulation=np.full(per_period, np.nan),
            offset=np.full(per_period, np.nan),
            period_valid=np.zeros(per_period, bool),
            finest_used=np.full(per_axis, -1, np.int8),
            residual=np.full(per_axis, np.nan),
            period_residual=np.full(per_period, np.nan),
            noise_mm=np.full(per_axis, np.nan),
            predicted_noise_mm=np.full(per_axis, np.nan),
            margin=np.full(per_axis, np.nan),
            lit=None,
            region=None,
            valid=np.zeros((height, width), bool),
            threshold=math.nan,
            normalised=False,
            response="linear",
        )


def prepared(capture: Capture, response: Response | None = None) -> tuple[np.ndarray, float, bool]:
    """The frames to decode, the peak response the threshold is based on, and whether
    they were normalised: through ``response`` where given, then ``(I - black) / (white
    - black)`` where both references exist (response 1; NaN where white is not above
    black), else as recorded with the capture's peak response (or, without one, the
    white's largest value above black, or the largest recorded value)."""
    peak = _peak(capture)
    if response is not None:
        return response.normalised(capture.frames, capture.black, capture.white, peak)
    frames = np.asarray(capture.frames, np.float64)
    if capture.black is not None and capture.white is not None:
        span = np.asarray(capture.white, np.float64) - capture.black
        with np.errstate(invalid="ignore", divide="ignore"):
            scale = np.where(span > 0, 1.0 / span, np.nan)
        return (frames - capture.black) * scale, 1.0, True
    return frames, peak, False


def _peak(capture: Capture) -> float:
    if capture.peak_response is not None:
        return float(capture.peak_response)
    if capture.white is not None:
        base = 0.0 if capture.black is None else float(np.nanmedian(capture.black))
        return float(np.nanmax(capture.white)) - base
    return float(np.nanmax(capture.frames))


def masks_of(
    capture: Capture, how: str
) -> tuple[np.ndarray | None, np.ndarray | None, float | None]:
    """``(lit, region, threshold)`` from the black and white references (None without
    them, or with ``how`` "all"): the white - black threshold of :func:`lit_threshold`."""
    if how == "all" or capture.black is None or capture.white is None:
        return None, None, None
    limit = lit_threshold(capture.black, capture.white)
    lit = lit_mask(capture.black, capture.white, limit)
    return lit, (lit & largest_region(lit)) if how == "region" else lit, limit


def decode_capture(
    capture: Capture,
    min_modulation_share: float = 0.1,
    settings: DecodeSettings | None = None,
    response: Response | None = None,
) -> CaptureDecoding:
    """Decode every coded direction of ``capture`` (``settings`` default: every period
    sound at ``min_modulation_share``, the mask of the lit region). The display response
    applied before black and white normalise: ``response``, else ``settings.response``,
    else the capture's own (none: linear)."""
    if settings is None:
        settings = DecodeSettings(min_modulation_share=min_modulation_share)
    given = (response, settings.response, capture.response)
    response = next((r for r in given if r is not None), None)
    coding = capture.coding
    frames, peak, normalised = prepared(capture, response)
    blocks = coding.glshade_order(frames)
    height, width = capture.shape
    periods = len(coding.periods)
    amplitude = 0.5 if coding.amplitude is None else coding.amplitude
    threshold = float(settings.min_modulation_share * amplitude * peak)
    maps = CaptureDecoding.empty(height, width, periods)
    noise_model = settings.noise
    if noise_model is None:
        from glshade.capture.noise import noise_of_scene

        noise_model = noise_of_scene(capture.scene)
    raw = coding.glshade_order(np.asarray(capture.frames, np.float64)) if noise_model else None
    for direction in coding.directions:
        axis = axis_of(direction)
        codec = coding.codec(direction)
        s = _decode_axis(maps, axis, blocks[direction], codec, threshold, settings.rule)
        size = coding.screen_size_mm[axis]
        if coding.origin[axis] == "high":
            s = size - s
        maps.uv[..., axis] = s - 0.5 * size
        maps.fraction[..., axis] = s / size
        if raw is not None and noise_model is not None:
            _predicted(maps, axis, raw[direction], codec, noise_model, capture.black)
    lit, region, lit_limit = masks_of(capture, settings.mask)
    valid = np.all(maps.finest_used[[axis_of(d) for d in coding.directions]] >= 0, axis=0)
    if region is not None:
        valid &= region
    maps.uv[~valid] = np.nan
    maps.fraction[~valid] = np.nan
    return replace(
        maps,
        predicted_noise_mm=maps.predicted_noise_mm if raw is not None else None,
        lit=lit,
        region=region,
        valid=valid,
        threshold=threshold,
        normalised=normalised,
        response="linear" if response is None else response.label,
        peak=peak,
        lit_threshold=lit_limit,
    )


def _decode_axis(
    maps: CaptureDecoding,
    axis: int,
    block: np.ndarray,
    codec: pmd.FringeCodec,
    threshold: float,
    rule: str,
) -> np.ndarray:
    """One coded screen axis, filled into ``maps``: every tail of its periods decoded
    (periods ``k`` on), the pixel's coordinate from the finest tail the ``rule`` accepts
    (:func:`accepted`); returns ``s`` (mm from the coding's edge)."""
    direction = "u" if axis == 0 else "v"
    periods = codec.periods_mm
    tails = [
        pmd.decode(
            block[k:],
            replace(codec, periods_mm=periods[k:]),
            min_modulation=0.0,
            direction=direction,
        )
        for k in range(len(periods))
    ]
    whole = tails[0]
    maps.modulation[axis], maps.offset[axis] = whole.modulation, whole.offset
    sound = (whole.modulation >= threshold) & np.isfinite(whole.offset)
    maps.period_valid[axis] = sound
    margins = np.stack([_margin(whole, tails, periods, k) for k in range(len(periods))])
    floor = whole.modulation >= FLOOR_SHARE * threshold
    ok = accepted(rule, sound, floor, margins)
    used = np.full(block.shape[2:], -1, np.int8)
    for k in range(len(periods)):
        used[(used < 0) & ok[k]] = k
    maps.finest_used[axis] = used
    residuals = _period_residuals(block, whole, codec.shifts_rad)
    maps.period_residual[axis] = residuals
    maps.residual[axis] = np.sqrt(np.mean(residuals**2, axis=0))
    sigma = maps.residual[axis] * _dof_factor(codec.shifts)
    s = np.full(block.shape[2:], np.nan)
    noise = np.full(block.shape[2:], np.nan)
    for k in range(len(periods)):
        here = used == k
        s[here] = tails[k].s_mm[here]
        with np.errstate(invalid="ignore", divide="ignore"):
            unit = pmd.predicted_noise_mm(replace(codec, periods_mm=periods[k:]), 1.0, 1.0)
            noise[here] = unit * sigma[here] / whole.modulation[k][here]
    maps.noise_mm[axis] = noise
    maps.margin[axis] = np.take_along_axis(margins, np.maximum(used, 0)[None], 0)[0]
    maps.margin[axis][used < 0] = np.nan
    return s


def accepted(rule: str, sound: np.ndarray, floor: np.ndarray, margins: np.ndarray) -> np.ndarray:
    """(K, H, W): whether the coordinate may come from the periods ``k`` on (finest
    first). ``sound`` (K, H, W) each period's modulation at least the threshold,
    ``floor`` at least :data:`FLOOR_SHARE` of it, ``margins`` the least unwrapping
    margin from period ``k`` on (turns). "all": every period sound (tail 0 alone);
    "fallback": every period from ``k`` on sound; "periods": every period coarser than
    ``k`` sound (they unwrap it), period ``k`` above the floor, and the unwrapping
    unambiguous (every margin from ``k`` on at least :data:`MIN_MARGIN_TURNS`)."""
    count = sound.shape[0]
    from_k = np.stack([sound[k:].all(axis=0) for k in range(count)])
    if rule == "all":
        return np.concatenate([from_k[:1], np.zeros_like(from_k[1:])])
    if rule == "fallback":
        return from_k
    coarser = np.concatenate([from_k[1:], np.ones_like(from_k[:1])])
    with np.errstate(invalid="ignore"):
        return coarser & floor & (margins >= MIN_MARGIN_TURNS)


def _period_residuals(block: np.ndarray, decoded: pmd.Decoded, steps: np.ndarray) -> np.ndarray:
    """(K, H, W): per period the rms over shifts of ``I - (A + B cos(φ - δ_n))``."""
    total = np.zeros(decoded.offset.shape)
    for n, step in enumerate(steps):
        fit = decoded.offset + decoded.modulation * np.cos(decoded.wrapped - step)
        total += (block[:, n] - fit) ** 2
    return np.sqrt(total / len(steps))


def _dof_factor(shifts: int) -> float:
    """The noise σ over the residual rms of an N-step fit (3 parameters: N - 3 degrees
    of freedom left; N = 3 fits exactly and the residual says nothing: NaN)."""
    return math.sqrt(shifts / (shifts - 3)) if shifts > 3 else math.nan


def _margin(
    whole: pmd.Decoded, tails: list[pmd.Decoded], periods: tuple[float, ...], start: int
) -> np.ndarray:
    """The least unwrapping margin over the steps from period ``start`` on: at step ``k``
    the coarser estimate ``s_{k+1}`` (the decoder on the periods from ``k+1`` on) in turns
    of period ``k`` less the wrapped phase, its distance to the nearest half turn."""
    least = np.full(whole.offset.shape[1:], 0.5)
    for k in range(start, len(periods) - 1):
        turns = tails[k + 1].s_mm / periods[k] - whole.wrapped[k] / (2.0 * np.pi)
        least = np.fmin(least, 0.5 - np.abs(turns - np.round(turns)))
    return least


def _predicted(
    maps: CaptureDecoding,
    axis: int,
    raw: np.ndarray,
    codec: pmd.FringeCodec,
    noise: CameraNoise,
    black: np.ndarray | None,
) -> None:
    """The coordinate's noise the camera's noise model predicts (into
    ``maps.predicted_noise_mm``), from the recorded (raw) frames' offset and modulation at
    the finest period used."""
    assert maps.predicted_noise_mm is not None
    decoded = pmd.decode(raw, codec, min_modulation=0.0)
    level = noise.black if black is None else np.asarray(black, np.float64)
    used = maps.finest_used[axis]
    for k in range(len(codec.periods_mm)):
        here = used == k
        sigma = noise.sigma(decoded.offset[k] - level)
        unit = pmd.predicted_noise_mm(replace(codec, periods_mm=codec.periods_mm[k:]), 1.0, 1.0)
        with np.errstate(invalid="ignore", divide="ignore"):
            maps.predicted_noise_mm[axis][here] = (unit * sigma / decoded.modulation[k])[here]
