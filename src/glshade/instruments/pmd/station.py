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

from glshade.frame import Region
from glshade.instruments.pmd.baseline import (
    PmdBaseline,
    median_share,
    pasted,
    pmd_baseline,
)
from glshade.instruments.pmd.capture import (
    Decoding,
    failures,
    interior,
)
from glshade.instruments.pmd.model import StationModel, station_model
from glshade.instruments.pmd.reconstruct import (
    Heights,
    reconstruct,
    slope_map,
)
from glshade.instruments.pmd.settings import PmdSettings, check_scene
from glshade.instruments.pmd.shots import Shot, shoot
from glshade.instruments.pmd.status import assess_pmd
from glshade.scene import Scene

if TYPE_CHECKING:
    from glshade.rendering import Renderer

#: The share of its largest move above which a pixel belongs to the dent's region.
REGION_SHARE = 0.2
#: A dent's sequence is traced over this many σ (its largest) about its centre, or the
#: height grid's reach where that is more (:func:`trace_region`) ...
TRACE_SIGMAS = 5.0
#: ... and this many pixels more on every side.
TRACE_MARGIN_PX = 2


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
    ``recorded`` the case's recorded sequence (F, H, W, in the order shown) where its
    frames were kept, else its first frame (1, H, W), ``recording`` how it was recorded,
    ``traced`` the region its own frames cover (None: the whole image; the defect-free
    scene's outside it)."""

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
    traced: Region | None = None


def seen_in_both(
    exact0: np.ndarray, exact1: np.ndarray, axes: list[int], within: np.ndarray | None = None
) -> np.ndarray:
    """Pixels whose every coded coordinate is finite in both exact maps, off their edge
    (:func:`interior`; ``within``: of those pixels alone)."""
    seen = np.all(np.isfinite(exact0[..., axes]), axis=-1)
    return interior(seen & np.all(np.isfinite(exact1[..., axes]), axis=-1), within)


def dent_region(model: StationModel, exact0: np.ndarray, exact1: np.ndarray) -> np.ndarray:
    """Where, inside its window and off the edge of what sees the screen
    (:func:`interior`), the dent moves the exact screen points by at least
    :data:`REGION_SHARE` of its largest move."""
    window, axes = model.window, list(model.axes)
    moved = np.linalg.norm((exact1 - exact0)[..., axes], axis=-1)
    moved = np.where(seen_in_both(exact0, exact1, axes, window), moved, 0.0)
    peak = float(moved.max()) if moved.size else 0.0
    if peak <= 0.0:
        return np.zeros(moved.shape, bool)
    return moved >= REGION_SHARE * peak


def trace_region(scene: Scene, settings: PmdSettings) -> Region | None:
    """The pixels a dent's sequence is traced over once its geometry's defect-free one
    exists (None: the whole image). Outside, the frames are the defect-free scene's: the
    box holds the square ``±R`` about the dent's centre on the surface, ``R`` the larger
    of :data:`TRACE_SIGMAS` and the height grid's ``window_sigmas`` times its largest σ,
    projected and padded (:func:`~glshade.metrics.status.surface_box`) and grown by
    :data:`TRACE_MARGIN_PX`; beyond :data:`TRACE_SIGMAS` a Gaussian dent's slope is below
    3.1e-5 of its steepest (``5 e^{-12.5} / e^{-1/2}``). The whole image where that box
    cannot be trusted: a lens (each pixel sees a blur circle), a point behind the camera
    or off the surface."""
    from glshade.metrics.status import surface_box

    height, width = scene.camera.height, scene.camera.width
    if scene.active.camera.samples(scene) > 1:
        return None
    defect = scene.defect
    cov = np.array([[defect.sigma_x2, defect.sigma_xz], [defect.sigma_xz, defect.sigma_z2]])
    reach = max(TRACE_SIGMAS, settings.window_sigmas) * math.sqrt(
        float(np.linalg.eigvalsh(cov).max())
    )
    steps = np.linspace(-reach, reach, 9)
    x, z = np.meshgrid(defect.x0 + steps, defect.z0 + steps)
    box = surface_box(scene, (height, width), x.ravel(), z.ravel())
    if box is None:
        return None
    found = Region.of_mask(box)
    if found is None:
        return Region(0, 0, 0, 0)
    return found.grown(TRACE_MARGIN_PX, height, width)


def measure_pmd_scene(
    renderer: Renderer,
    scene: Scene,
    settings: PmdSettings = PmdSettings(),
    baseline: PmdBaseline | None = None,
    *,
    keep_frames: bool = False,
    whole_frame: bool = False,
) -> PmdResult:
    """What a PMD station measures of ``scene``'s dent, on an existing renderer
    (``baseline``: the defect-free analysis of the same geometry, when the caller has
    it; without one, a case whose buffers and analysis would exceed the renderer's memory
    budget is refused first, in one line: :func:`glshade.instruments.memory.check_pmd`).
    The frames are rendered from ``scene`` over its :func:`trace_region` (the
    defect-free scene's outside it: :func:`composed`); decoding, slopes and heights use
    the station's model of it (:func:`~glshade.instruments.pmd.model.station_model`).
    ``keep_frames``: every recorded frame kept (``maps.recorded``: the dent's own inside
    the region, the defect-free scene's outside, as its maps); ``whole_frame``: the
    dent's sequence traced over the whole image, the numbers the same."""
    model = station_model(scene)
    if baseline is None:
        from glshade.instruments.memory import check_pmd

        check_pmd(scene, renderer.memory_budget_bytes)
        baseline = pmd_baseline(renderer, model, settings, keep_frames=keep_frames)
    box = trace_region(scene, settings)
    if keep_frames and baseline.capture.recorded is None:
        box = None  # no defect-free frames to keep outside a box: the dent's own, whole
    own = None
    if whole_frame or box is None or (box.rows and box.cols):
        own = shoot(
            renderer,
            scene,
            model.coding,
            settings,
            region=None if whole_frame else box,
            peak=baseline.capture.peak_response,
            keep_frames=keep_frames,
        )
    shot = composed(baseline.capture, own, box)
    start = time.perf_counter()
    twin = baseline.twin_over(renderer, model.window)
    twin_s = time.perf_counter() - start
    start = time.perf_counter()
    slopes = slope_map(model, baseline.nominal, shot.decoding.uv, box)
    if box is not None:  # the defect-free scene's outside, as the frames
        slopes = np.where(np.isnan(slopes), baseline.slopes, slopes)
    heights = reconstruct(model, baseline.nominal, slopes, settings, box)
    heights_s = time.perf_counter() - start
    seconds = dict(own.seconds) if own is not None else {"render": 0.0, "decode": 0.0}
    seconds.update(twin=twin_s, heights=heights_s)
    case = _Case(model, shot, twin, slopes, heights, box)
    return _result(scene, baseline, case, seconds)


def composed(base: Shot, own: Shot | None, box: Region | None) -> Shot:
    """The dent's shot over the whole image: its own (``own``) inside ``box`` (None: the
    whole image, ``own`` whole), the defect-free scene's (``base``, whole) outside, where
    the dent changes nothing the frames resolve (:func:`trace_region`); ``own``'s
    recorded frames too, where both kept them."""
    if box is None:
        assert own is not None and own.region.rows == base.region.rows
        return own
    decoding = base.decoding
    whole = Decoding(
        decoding.uv.copy(),
        decoding.valid.copy(),
        decoding.modulation.copy(),
        decoding.offset.copy(),
        decoding.wrapped.copy(),
        decoding.threshold,
    )
    uv, white, share = base.uv.copy(), base.white.copy(), base.share.copy()
    first, recorded_white = base.first.copy(), base.recorded_white.copy()
    recorded = None if base.recorded is None else base.recorded.copy()
    if own is not None and box.rows and box.cols:
        local = _within(box, own.region)
        part = _cut(own.decoding, local)
        pasted(whole, part, box)
        rows, cols = box.slices
        lr, lc = local.slices
        uv[rows, cols] = own.uv[lr, lc]
        white[rows, cols] = own.white[lr, lc]
        share[:, rows, cols] = own.share[:, lr, lc]
        first[rows, cols] = own.first[lr, lc]
        recorded_white[rows, cols] = own.recorded_white[lr, lc]
        if recorded is not None and own.recorded is not None:
            recorded[:, rows, cols] = own.recorded[:, lr, lc]
    return Shot(
        Region(0, 0, *base.uv.shape[:2]),
        uv,
        white,
        base.gain,
        base.black_level,
        base.peak_response,
        whole,
        share,
        first,
        recorded_white,
        recorded,
        own.seconds if own is not None else {},
    )


def _within(box: Region, outer: Region) -> Region:
    """``box`` in the coordinates of the region ``outer`` that holds it."""
    return Region(box.row0 - outer.row0, box.col0 - outer.col0, box.rows, box.cols)


def _cut(decoding: Decoding, local: Region) -> Decoding:
    """``decoding`` cut to ``local`` (a region of its arrays)."""
    rows, cols = local.slices
    return Decoding(
        decoding.uv[rows, cols],
        decoding.valid[rows, cols],
        decoding.modulation[:, :, rows, cols],
        decoding.offset[:, :, rows, cols],
        decoding.wrapped[:, :, rows, cols],
        decoding.threshold,
    )


@dataclass(frozen=True)
class _Case:
    """One case's shot (the whole image's: :func:`composed`) and analysis, before its
    numbers are taken: ``twin`` the defect-free scene's second decoding over the dent's
    window (None without a sensor), ``box`` the traced region (None: the whole image)."""

    model: StationModel
    shot: Shot
    twin: Decoding | None
    slopes: np.ndarray
    heights: Heights
    box: Region | None


def _result(
    scene: Scene, baseline: PmdBaseline, case: _Case, seconds: dict[str, float]
) -> PmdResult:
    model, shot = case.model, case.shot
    decoding = shot.decoding
    axes = list(model.axes)
    base, exact0 = baseline.decoding, baseline.capture.uv
    window = model.window
    failed = failures(decoding.uv, shot.uv, model)
    # valid in both decodes and off the edge of that region (a pixel straddling it mixes
    # the screen with the curtain: :func:`interior`)
    both = interior(decoding.valid & base.valid, window)
    both &= ~failed & ~failures(base.uv, exact0, model)
    shift = np.linalg.norm((decoding.uv - base.uv)[..., axes], axis=-1)
    moved = np.linalg.norm((shot.uv - exact0)[..., axes], axis=-1)
    moved = np.where(seen_in_both(exact0, shot.uv, axes, window), moved, np.nan)
    noise = baseline.noise(window, case.twin)
    region = dent_region(model, exact0, shot.uv)
    exact_mm = _largest(moved)
    status = assess_pmd(
        scene, model, baseline, shot, region, failed, exact_mm, noise, case.twin is not None
    )
    shift_mm = _largest(np.where(both, shift, np.nan))
    slopes = case.slopes
    slope = np.hypot(slopes[..., 0], slopes[..., 1])
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
        decode_rms_mm=baseline.decode_rms_mm,
        unwrap_failures=int(failed.sum()),
        valid_fraction=_valid_share(decoding, shot.uv[..., axes[0]]),
        modulation=median_share(model.axes, shot.share, region),
        status=status.status,
        status_reason=status.reason,
        maps=_maps(baseline, case, failed, region, both),
        seconds=seconds,
    )


def _maps(
    baseline: PmdBaseline,
    case: _Case,
    failed: np.ndarray,
    region: np.ndarray,
    shift_pixels: np.ndarray,
) -> PmdMaps:
    shot = case.shot
    decoding, exact = shot.decoding, shot.uv
    base = baseline.decoding
    recorded = shot.recorded if shot.recorded is not None else shot.first[None]
    recording = Recording(
        shot.gain,
        shot.black_level,
        shot.peak_response,
        decoding.threshold,
        baseline.settings.modulation_share if baseline.settings.min_modulation is None else None,
        shot.recorded_white,
    )
    return PmdMaps(
        decoded=decoding.uv,
        exact=exact,
        error=decoding.uv - exact,
        exact_defect_free=baseline.capture.uv,
        decoded_defect_free=base.uv,
        decoded_twin=base.uv if case.twin is None else case.twin.uv,
        modulation=decoding.modulation,
        wrapped=decoding.wrapped,
        modulation_share=shot.share,
        slopes_urad=(1e6 * case.slopes).astype(np.float32),
        height_um=case.heights.per_pixel_um,
        heights=case.heights,
        failed=failed,
        region=region,
        shift_pixels=shift_pixels,
        noise_pixels=baseline.noise_pixels(case.model.window, case.twin),
        recorded=recorded,
        recording=recording,
        traced=case.box,
    )


def _largest(values: np.ndarray) -> float:
    """The largest finite value (NaN for none)."""
    finite = values[np.isfinite(values)]
    return float(finite.max()) if finite.size else math.nan


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
