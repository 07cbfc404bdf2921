"""Phase-measuring deflectometry, measured: what a PMD station would measure of a scene's
dent (docs/pmd.md).

A case renders the fringe sequence of the scene and of its defect-free twin through the
whole imaging chain (one trace each: every ray is shaded for every frame,
:meth:`Renderer.render <glshade.gpu.renderer.Renderer.render>` with the ``frames``
output), records each frame with the sensor's own noise, decodes both like a station
(:mod:`glshade.instruments.pmd.decode`), and compares:

- the decoded screen points with and without the dent (``pmd_shift_mm``), against the
  noise of two decodes of the defect-free scene with different seeds (``pmd_noise_mm``)
  and its prediction from the modulation;
- the decoded points against the exact map the renderer traced (``decode_rms_mm``,
  ``unwrap_failures``);
- the measured normals (each pixel's point taken on the nominal surface, as a station
  takes it on the part's CAD model) against the nominal ones: the slope map, integrated
  on a regular ``(x, z)`` grid around the dent into heights, and the Gaussian fitted to
  them (``pmd_depth_um``).

The defect-free analysis (:class:`~glshade.instruments.pmd.baseline.PmdBaseline`) is
shared by every dent on one geometry, as the paper metric's
:class:`~glshade.metrics.visibility.Baseline` is. The case's parts live beside this
module: its settings (:mod:`.settings`), capture and decoding (:mod:`.capture`), the
defect-free analysis (:mod:`.baseline`), slopes and heights (:mod:`.reconstruct`) and its
status (:mod:`.status`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from glshade.instruments.pmd.baseline import (
    PmdBaseline,
    median_share,
    modulation_share,
    pmd_baseline,
)
from glshade.instruments.pmd.capture import (
    Capture,
    Decoding,
    capture,
    decode_sequence,
    failures,
    interior,
    seen_pixels,
)
from glshade.instruments.pmd.model import StationModel, station_model
from glshade.instruments.pmd.reconstruct import (
    Heights,
    reconstruct,
    slope_map,
)
from glshade.instruments.pmd.settings import PmdSettings, check_scene
from glshade.instruments.pmd.status import assess_pmd
from glshade.scene import Scene

if TYPE_CHECKING:
    from glshade.rendering import Renderer

#: The share of its largest move above which a pixel belongs to the dent's region.
REGION_SHARE = 0.2


# --------------------------------------------------------------------------- one case
@dataclass(frozen=True)
class PmdResult:
    """What a PMD station measures of one scene's dent (lengths on the screen in mm,
    slopes in µrad, heights in µm) with its status, the maps behind the numbers and the
    seconds spent."""

    pmd_shift_mm: float
    pmd_shift_exact_mm: float
    pmd_noise_mm: float
    pmd_noise_floor_mm: float
    pmd_noise_predicted_mm: float
    pmd_snr: float
    pmd_slope_urad: float
    pmd_depth_um: float
    pmd_sigma_mm: float
    decode_rms_mm: float
    unwrap_failures: int
    valid_fraction: float
    modulation: float
    status: str
    status_reason: str
    maps: PmdMaps
    seconds: dict[str, float]


@dataclass(frozen=True)
class Recording:
    """How a case's frames were recorded, what decoding them takes: ``gain`` the exposure
    applied (``camera.exposure`` as a number, ``"auto"`` worked out: radiance ``1 / gain``
    fills the full well, the range from the black level to full scale; 1 without a
    sensor), ``black_level`` (recorded units, full scale 1; 0 without a sensor),
    ``white_response`` the brightest pixel's noise-free response to the screen's white
    above the black level (the validity threshold's base), ``threshold`` the modulation a
    valid pixel needs (recorded units) and ``modulation_share`` the share of ``amplitude``
    times ``white_response`` it is (None where ``PmdSettings.min_modulation`` set it),
    ``white`` (H, W) the screen's white as recorded."""

    gain: float
    black_level: float
    white_response: float
    threshold: float
    modulation_share: float | None
    white: np.ndarray


@dataclass(frozen=True)
class PmdMaps:
    """The maps of one case, image-aligned (H, W[, 2]) unless said; every per-direction
    axis in the screen's order (u, v), NaN for a coordinate the sequence does not code.

    ``decoded`` the decoded screen points (mm, NaN invalid), ``exact`` the traced ones,
    ``error`` decoded minus exact (mm); the defect-free scene's ``exact_defect_free``,
    ``decoded_defect_free`` and ``decoded_twin`` (its second recording, another seed: the
    noise; without a sensor the same radiance, so the same decode); ``modulation`` and
    ``wrapped`` (2, K, H, W; NaN where no screen is seen), ``modulation_share`` (2, H, W:
    :func:`modulation_share`); ``slopes_urad``, ``height_um`` and the heights' grid;
    ``failed`` (unwrapping failures), ``region`` (the dent's region), ``shift_pixels`` and
    ``noise_pixels`` (the pixels ``pmd_shift_mm`` and ``pmd_noise_mm`` are taken over);
    ``recorded`` the case's recorded sequence (F, H, W, in the order shown) and
    ``recording`` how it was recorded."""

    decoded: np.ndarray
    exact: np.ndarray
    error: np.ndarray
    exact_defect_free: np.ndarray
    decoded_defect_free: np.ndarray
    decoded_twin: np.ndarray
    modulation: np.ndarray
    wrapped: np.ndarray
    modulation_share: np.ndarray
    slopes_urad: np.ndarray
    height_um: np.ndarray
    heights: Heights
    failed: np.ndarray
    region: np.ndarray
    shift_pixels: np.ndarray
    noise_pixels: np.ndarray
    recorded: np.ndarray
    recording: Recording


def seen_in_both(exact0: np.ndarray, exact1: np.ndarray, axes: list[int]) -> np.ndarray:
    """Pixels whose every coded coordinate is finite in both exact maps, off their edge
    (:func:`interior`)."""
    seen = np.all(np.isfinite(exact0[..., axes]), axis=-1)
    return interior(seen & np.all(np.isfinite(exact1[..., axes]), axis=-1))


def dent_region(model: StationModel, exact0: np.ndarray, exact1: np.ndarray) -> np.ndarray:
    """Where, inside its window and off the edge of what sees the screen
    (:func:`interior`), the dent moves the exact screen points by at least
    :data:`REGION_SHARE` of its largest move."""
    window, axes = model.window, list(model.axes)
    moved = np.linalg.norm((exact1 - exact0)[..., axes], axis=-1)
    moved = np.where(window & seen_in_both(exact0, exact1, axes), moved, 0.0)
    peak = float(moved.max()) if moved.size else 0.0
    if peak <= 0.0:
        return np.zeros(moved.shape, bool)
    return moved >= REGION_SHARE * peak


def measure_pmd_scene(
    renderer: Renderer,
    scene: Scene,
    settings: PmdSettings = PmdSettings(),
    baseline: PmdBaseline | None = None,
) -> PmdResult:
    """What a PMD station measures of ``scene``'s dent, on an existing renderer
    (``baseline``: the defect-free analysis of the same geometry, when the caller has
    it; without one, a case whose buffers and analysis would exceed the renderer's memory
    budget is refused first, in one line: :func:`glshade.instruments.memory.check_pmd`).
    The frames are rendered from ``scene``; decoding, slopes and heights use the
    station's model of it (:func:`~glshade.instruments.pmd.model.station_model`)."""
    model = station_model(scene)
    if baseline is None:
        from glshade.instruments.memory import check_pmd

        check_pmd(scene, renderer.memory_budget_bytes)
        baseline = pmd_baseline(renderer, model, settings)
    shot = capture(renderer, scene)
    start = time.perf_counter()
    recorded = shot.recorded()
    peak = baseline.capture.peak_response
    decoding = decode_sequence(model.coding, recorded, peak, settings, seen_pixels(shot.uv))
    share = settings.modulation_share if settings.min_modulation is None else None
    white = shot.recorded_white()
    recording = Recording(shot.gain, shot.black_level, peak, decoding.threshold, share, white)
    decode_s = time.perf_counter() - start
    start = time.perf_counter()
    slopes = slope_map(model, baseline.nominal, decoding.uv)
    heights = reconstruct(model, baseline.nominal, slopes, settings)
    heights_s = time.perf_counter() - start
    seconds = {"render": shot.seconds, "decode": decode_s, "heights": heights_s}
    case = _Case(model, shot, recorded, recording, decoding, slopes, heights)
    return _result(scene, baseline, case, seconds)


@dataclass(frozen=True)
class _Case:
    """One case's capture and analysis, before its numbers are taken."""

    model: StationModel
    shot: Capture
    recorded: np.ndarray
    recording: Recording
    decoding: Decoding
    slopes: np.ndarray
    heights: Heights


def _result(
    scene: Scene, baseline: PmdBaseline, case: _Case, seconds: dict[str, float]
) -> PmdResult:
    model, shot, decoding = case.model, case.shot, case.decoding
    axes = list(model.axes)
    base, exact0 = baseline.decoding, baseline.capture.uv
    window = model.window
    failed = failures(decoding.uv, shot.uv, model)
    # valid in both decodes and off the edge of that region (a pixel straddling it mixes
    # the screen with the curtain: :func:`interior`)
    both = window & interior(decoding.valid & base.valid)
    both &= ~failed & ~failures(base.uv, exact0, model)
    shift = np.linalg.norm((decoding.uv - base.uv)[..., axes], axis=-1)
    moved = np.linalg.norm((shot.uv - exact0)[..., axes], axis=-1)
    moved = np.where(window & seen_in_both(exact0, shot.uv, axes), moved, np.nan)
    noise = baseline.noise(window)
    region = dent_region(model, exact0, shot.uv)
    exact_mm = _largest(moved)
    status = assess_pmd(scene, model, baseline, shot, decoding, region, failed, exact_mm, noise)
    shift_mm = _largest(np.where(both, shift, np.nan))
    slopes = case.slopes
    slope = np.hypot(slopes[..., 0], slopes[..., 1])
    share = modulation_share(model.coding, shot)
    dent = case.heights.dent
    return PmdResult(
        pmd_shift_mm=shift_mm,
        pmd_shift_exact_mm=exact_mm,
        pmd_noise_mm=noise.std,
        pmd_noise_floor_mm=noise.floor,
        pmd_noise_predicted_mm=noise.predicted,
        pmd_snr=shift_mm / noise.std if noise.std > 0 else math.inf,
        pmd_slope_urad=1e6 * _largest(np.where(region & decoding.valid & ~failed, slope, np.nan)),
        pmd_depth_um=dent.depth if dent is not None else math.nan,
        pmd_sigma_mm=dent.sigma_mm if dent is not None else math.nan,
        decode_rms_mm=_decode_rms(baseline),
        unwrap_failures=int(failed.sum()),
        valid_fraction=_valid_share(decoding, shot.uv[..., axes[0]]),
        modulation=median_share(model.axes, share, region),
        status=status.status,
        status_reason=status.reason,
        maps=_maps(baseline, case, share, failed, region, both),
        seconds=seconds,
    )


def _maps(
    baseline: PmdBaseline,
    case: _Case,
    share: np.ndarray,
    failed: np.ndarray,
    region: np.ndarray,
    shift_pixels: np.ndarray,
) -> PmdMaps:
    decoding, exact = case.decoding, case.shot.uv
    base = baseline.decoding
    return PmdMaps(
        decoded=decoding.uv,
        exact=exact,
        error=decoding.uv - exact,
        exact_defect_free=baseline.capture.uv,
        decoded_defect_free=base.uv,
        decoded_twin=base.uv if baseline.twin is None else baseline.twin.uv,
        modulation=decoding.modulation,
        wrapped=decoding.wrapped,
        modulation_share=share,
        slopes_urad=(1e6 * case.slopes).astype(np.float32),
        height_um=case.heights.per_pixel_um,
        heights=case.heights,
        failed=failed,
        region=region,
        shift_pixels=shift_pixels,
        noise_pixels=baseline.noise_pixels(case.model.window),
        recorded=case.recorded,
        recording=case.recording,
    )


def _largest(values: np.ndarray) -> float:
    """The largest finite value (NaN for none)."""
    finite = values[np.isfinite(values)]
    return float(finite.max()) if finite.size else math.nan


def _decode_rms(baseline: PmdBaseline) -> float:
    """Root mean square of the defect-free scene's decoded minus exact points over its valid
    pixels that did not fail to unwrap, each coded coordinate counted."""
    base, exact = baseline.decoding, baseline.capture.uv
    ok = base.valid & ~failures(base.uv, exact, baseline.model)
    error = (base.uv - exact)[ok][:, list(baseline.model.axes)]
    return float(np.sqrt(np.mean(error**2))) if error.size else math.nan


def _valid_share(decoding: Decoding, exact: np.ndarray) -> float:
    """Valid pixels over the pixels that see the screen."""
    seen = np.isfinite(exact)
    return float(decoding.valid[seen].mean()) if seen.any() else 0.0


def measure_pmd(
    scene: Scene, *, renderer: Renderer | None = None, settings: PmdSettings | None = None
) -> PmdResult:
    """:func:`measure_pmd_scene` with a renderer of its own unless one is given."""
    settings = settings or PmdSettings()
    check_scene(scene)
    if renderer is not None:
        return measure_pmd_scene(renderer, scene, settings)
    from glshade.gpu.renderer import Renderer

    with Renderer() as own:
        return measure_pmd_scene(own, scene, settings)


def summary(result: PmdResult) -> dict[str, Any]:
    """The result's numbers (no maps)."""
    return {
        name: getattr(result, name)
        for name in PmdResult.__dataclass_fields__
        if name not in ("maps", "seconds")
    }
