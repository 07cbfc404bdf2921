"""Phase-measuring deflectometry (PMD): the fringe coding, its decoding, and from decoded
slopes to heights (docs/pmd.md).

An inspection station shows sinusoidal fringes on a screen, at ``N`` phase shifts and
``K`` periods per direction, and decodes for every camera pixel the screen point it sees.
This module is the station's side, pure NumPy/SciPy and independent of rendering:

- :class:`FringeCodec`: the coding, the one the fringe emitter shows
  (:mod:`glshade.components.emitter.fringes.codec`), validated when made; its
  :meth:`~FringeCodec.radiance` and :meth:`~FringeCodec.sequence` are what a frame
  displays at a screen coordinate, the renderer's formula in float64 (the generator of
  synthetic sequences).
- :func:`decode`: wrapped phases, modulation, offset and temporal unwrapping of one
  direction's ``(K, N, H, W)`` sequence into the screen coordinate ``s`` (mm from the
  screen's edge).
- :func:`unwrap_failures`, :func:`predicted_noise_mm`: against the exact map, and the
  noise a decoder should reach.
- :func:`normals_from_points`, :func:`slope_deviation`: the measured normals from the
  decoded screen points, and their slopes against the nominal normals.
- :func:`integrate_slopes`, :func:`remove_plane`, :func:`dent_from_height`: least-squares
  (or Frankot-Chellappa) heights from slope maps, and the Gaussian dent they hold.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from glshade.components.emitter.fringes.codec import FringeCodec
from glshade.errors import GlshadeError

if TYPE_CHECKING:
    from scipy.sparse import csr_matrix


@dataclass(frozen=True)
class Decoded:
    """One direction decoded. ``s_mm``: the screen coordinate (mm from its edge, NaN where
    not valid); ``modulation`` (K, H, W): ``B_k``; ``offset`` (K, H, W): ``A_k``;
    ``wrapped`` (K, H, W): the phases in [0, 2π); ``valid``: every ``B_k`` at least the
    threshold."""

    s_mm: np.ndarray
    modulation: np.ndarray
    offset: np.ndarray
    wrapped: np.ndarray
    valid: np.ndarray


def decode(
    frames: np.ndarray,
    coding: FringeCodec,
    peak_response: float = 1.0,
    min_modulation: float | None = None,
    direction: str | None = None,
) -> Decoded:
    """Decode one direction's ``(K, N, H, W)`` sequence (frame ``(k, n)`` at period ``k``,
    shift ``n``; ``direction``: which of the coding's, None where it codes one alone).
    The coding is taken as made (validated then); it is not checked again here, and
    :meth:`FringeCodec.check_decodable` is the caller's to ask (a station measurement
    asks it before anything is rendered).

    ``φ_k = atan2(Σ I_n sin δ_n, Σ I_n cos δ_n)`` in [0, 2π), ``B_k = (2/N) |Σ I_n
    e^{iδ_n}|``, ``A_k`` the mean; unwrapped from the coarsest period down, ``s_K = p_K
    φ_K / 2π`` (taken below 0 when it lies past the middle of the gap between the screen's
    extent and ``p_K``: noise wrapped it round) and ``s_k = p_k (φ_k + 2π round((2π
    s_{k+1} / p_k - φ_k) / 2π)) / 2π``; the result is ``s_1``. Valid where every ``B_k >=
    min_modulation`` (default 0.1 of ``amplitude`` times ``peak_response``, the image's
    response to the screen's white)."""
    frames = np.asarray(frames)
    periods = np.asarray(coding.periods_mm)
    extent = coding.extent_mm(direction)
    if frames.ndim < 3 or frames.shape[:2] != (len(periods), coding.shifts):
        raise GlshadeError(
            f"decode: frames must have shape ({len(periods)}, {coding.shifts}, ...) for this "
            f"coding, got {frames.shape}"
        )
    sine, cosine, offset = _phasor_sums(frames, coding.shifts_rad)
    wrapped = np.mod(np.arctan2(sine, cosine), 2.0 * np.pi)
    modulation = (2.0 / coding.shifts) * np.hypot(sine, cosine)
    threshold = 0.1 * coding.amplitude * peak_response if min_modulation is None else min_modulation
    valid = np.all(modulation >= threshold, axis=0) & np.isfinite(offset).all(axis=0)
    s = coarsest_coordinate(wrapped[-1], periods[-1], extent)
    for k in range(len(periods) - 2, -1, -1):
        s = unwrap_step(s, wrapped[k], periods[k])
    return Decoded(np.where(valid, s, np.nan), modulation, offset, wrapped, valid)


def coarsest_coordinate(wrapped: np.ndarray, period_mm: float, extent_mm: float) -> np.ndarray:
    """The coordinate (mm from the screen's edge) the coarsest period's wrapped phase
    gives, ``p φ / 2π``: the screen spans [0, extent] of it, so a coordinate past the
    middle of the gap beyond it is one just below 0 that the noise wrapped round."""
    s = period_mm * np.asarray(wrapped, np.float64) / (2.0 * np.pi)
    return np.where(s > 0.5 * (period_mm + extent_mm), s - period_mm, s)


def unwrap_step(coarser_mm: np.ndarray, wrapped: np.ndarray, period_mm: float) -> np.ndarray:
    """One temporal unwrapping step: the coordinate of the period ``period_mm`` whose
    wrapped phase is ``wrapped``, on the fringe the coarser coordinate points to,
    ``p (φ + 2π round((2π s / p - φ) / 2π)) / 2π``."""
    phase = np.asarray(wrapped, np.float64)
    turns = np.round((2.0 * np.pi * coarser_mm / period_mm - phase) / (2.0 * np.pi))
    return period_mm * (phase + 2.0 * np.pi * turns) / (2.0 * np.pi)


def _phasor_sums(
    frames: np.ndarray, steps_rad: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``Σ_n I_n sin δ_n``, ``Σ_n I_n cos δ_n`` and the mean over ``n`` of a ``(K, N, ...)``
    sequence, in float64, one shift at a time (no float64 copy of the whole sequence: the
    frames may be float32); NaN in a frame stays NaN."""
    shape = frames.shape[:1] + frames.shape[2:]
    sine, cosine, total = np.zeros(shape), np.zeros(shape), np.zeros(shape)
    for n, step in enumerate(steps_rad):
        frame = frames[:, n]
        sine += math.sin(step) * frame
        cosine += math.cos(step) * frame
        total += frame
    return sine, cosine, total / len(steps_rad)


def unwrap_failures(decoded_s: np.ndarray, exact_s: np.ndarray, finest_period_mm: float) -> int:
    """Valid pixels (finite ``decoded_s``) whose decoded coordinate differs from the exact
    one by more than half the finest period: the unwrapping chose the wrong fringe."""
    decoded_s, exact_s = np.asarray(decoded_s), np.asarray(exact_s)
    both = np.isfinite(decoded_s) & np.isfinite(exact_s)
    return int((np.abs(decoded_s[both] - exact_s[both]) > 0.5 * finest_period_mm).sum())


def predicted_noise_mm(coding: FringeCodec, sigma_intensity: float, modulation: float) -> float:
    """The decoded coordinate's noise from intensity noise ``σ_I`` at modulation ``B``:
    ``periods[0] / 2π · sqrt(2 / N) · σ_I / B`` (the finest period's phase noise, which the
    unwrapping keeps when it picks the right fringe)."""
    return (
        coding.periods_mm[0]
        / (2.0 * np.pi)
        * math.sqrt(2.0 / coding.shifts)
        * sigma_intensity
        / modulation
    )


# --------------------------------------------------------------------------- slopes
def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def normals_from_points(
    points: np.ndarray, camera_position: np.ndarray, screen_points: np.ndarray
) -> np.ndarray:
    """The measured unit normals ``(..., 3)``: at each surface point ``P`` the bisector of
    the directions from ``P`` to the camera and from ``P`` to its decoded screen point (a
    mirror that sends the camera's ray there). Arrays broadcast, float64; NaN in, NaN out."""
    p = np.asarray(points, np.float64)
    to_camera = _unit(np.asarray(camera_position, np.float64) - p)
    to_screen = _unit(np.asarray(screen_points, np.float64) - p)
    return _unit(to_camera + to_screen)


def slope_deviation(measured: np.ndarray, nominal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The slopes ``(∂d/∂x, ∂d/∂z)`` of a deviation ``d`` added along ``y`` (``+y`` up) that
    turns the ``nominal`` unit normals into the ``measured`` ones (both ``(..., 3)``):
    a normal ``n`` is that of a surface with gradient ``(-n_x / n_y, -n_z / n_y)``, and the
    deviation's slope is the measured gradient minus the nominal one. Dimensionless, i.e.
    rad for small slopes (the tangent of the tilt); what :func:`integrate_slopes` takes."""
    m = np.asarray(measured, np.float64)
    n = np.asarray(nominal, np.float64)
    gx = -m[..., 0] / m[..., 1] + n[..., 0] / n[..., 1]
    gz = -m[..., 2] / m[..., 1] + n[..., 2] / n[..., 1]
    return gx, gz


# --------------------------------------------------------------------------- heights
def integrate_slopes(
    slope_x: np.ndarray,
    slope_z: np.ndarray,
    spacing_mm: float | tuple[float, float],
    valid: np.ndarray | None = None,
    outside: np.ndarray | None = None,
    method: str = "least-squares",
) -> np.ndarray:
    """Heights (the slopes' unit times mm) on a regular grid from the slopes ``∂h/∂x``
    (along columns, spacing ``dx``) and ``∂h/∂z`` (along rows, spacing ``dz``;
    ``spacing_mm`` is ``(dx, dz)`` or one number for both).

    Every pair of valid 4-neighbours gives one equation (forward differences): their
    height difference equals the mean of their two slopes times the spacing. The least-
    squares solution comes from the normal equations, solved directly (SciPy's sparse
    ``spsolve``) with one height per connected valid region held at 0 (each region's
    free offset). Then the plane (tilt and offset) fitted over the valid pixels of
    ``outside`` (default: every valid pixel) is removed. NaN where not valid.

    ``method="frankot-chellappa"`` integrates in Fourier space instead (the slopes
    mirrored to an even height of twice the size, so the grid's edges do not wrap): only
    where every pixel is valid, a rectangle."""
    dx, dz = _spacings(spacing_mm)
    gx, gz = _slope_maps(slope_x, slope_z)
    ok = np.isfinite(gx) & np.isfinite(gz)
    if valid is not None:
        ok &= np.asarray(valid, bool)
    if method == "frankot-chellappa":
        if not ok.all():
            raise GlshadeError(
                f"integrate_slopes: frankot-chellappa needs every pixel valid, "
                f"{int((~ok).sum())} of {ok.size} are not"
            )
        return remove_plane(_frankot_chellappa(gx, gz, dx, dz), outside)
    if method != "least-squares":
        raise GlshadeError(
            f"integrate_slopes: method must be 'least-squares' or 'frankot-chellappa', "
            f"got {method!r}"
        )
    return _least_squares_heights(gx, gz, dx, dz, ok, outside)


def _spacings(spacing_mm: float | tuple[float, float]) -> tuple[float, float]:
    """The grid's spacings ``(dx, dz)`` from one number for both or a pair."""
    steps = np.broadcast_to(np.asarray(spacing_mm, np.float64), (2,))
    return float(steps[0]), float(steps[1])


def _slope_maps(slope_x: np.ndarray, slope_z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The two slope maps as float64, one line unless they are 2-D of one shape."""
    gx, gz = np.asarray(slope_x, np.float64), np.asarray(slope_z, np.float64)
    if gx.ndim != 2 or gx.shape != gz.shape:
        raise GlshadeError(
            f"integrate_slopes: slope maps must be 2-D of one shape, got {gx.shape}, {gz.shape}"
        )
    return gx, gz


def _least_squares_heights(
    gx: np.ndarray,
    gz: np.ndarray,
    dx: float,
    dz: float,
    ok: np.ndarray,
    outside: np.ndarray | None,
) -> np.ndarray:
    """:func:`integrate_slopes`' least-squares heights over the valid pixels ``ok`` (the
    normal equations solved directly, one height per connected region held at 0), the
    plane fitted where ``outside`` removed; NaN elsewhere."""
    from scipy.ndimage import label
    from scipy.sparse import diags
    from scipy.sparse.linalg import spsolve

    unknowns = int(ok.sum())
    heights = np.full(gx.shape, np.nan)
    if unknowns == 0:
        return heights
    index = np.full(gx.shape, -1)
    index[ok] = np.arange(unknowns)
    matrix, b = _difference_equations(index, gx, gz, dx, dz, unknowns)
    # each connected region's heights are known up to an offset: hold its first at 0
    regions, count = label(ok)
    _, first = np.unique(regions[ok], return_index=True)
    pin = np.zeros(unknowns)
    pin[first[:count]] = 1.0
    normal = (matrix.T @ matrix + diags(pin)).tocsc()
    heights[ok] = spsolve(normal, matrix.T @ b)
    return remove_plane(heights, outside, regions if count > 1 else None)


def _difference_equations(
    index: np.ndarray, gx: np.ndarray, gz: np.ndarray, dx: float, dz: float, unknowns: int
) -> tuple[csr_matrix, np.ndarray]:
    """The equations of every pair of valid 4-neighbours (``index``: each pixel's
    unknown, -1 where not valid), along the rows first and then the columns: the sparse
    matrix (CSR, a row per pair) and its right-hand side."""
    from scipy.sparse import coo_matrix

    along_x = _pair_equations(index[:, :-1], index[:, 1:], 0.5 * (gx[:, :-1] + gx[:, 1:]), dx, 0)
    along_z = _pair_equations(
        index[:-1, :], index[1:, :], 0.5 * (gz[:-1, :] + gz[1:, :]), dz, len(along_x.rhs[0])
    )
    b = np.concatenate(along_x.rhs + along_z.rhs)
    rows = np.concatenate(along_x.rows + along_z.rows)
    cols = np.concatenate(along_x.cols + along_z.cols)
    values = np.concatenate(along_x.values + along_z.values)
    matrix = coo_matrix((values, (rows, cols)), shape=(len(b), unknowns)).tocsr()
    return matrix, b


class _Equations(NamedTuple):
    """Sparse linear equations as lists of arrays: each entry's equation (row) and
    unknown (column), its coefficient, and each equation's right-hand side."""

    rows: list[np.ndarray]
    cols: list[np.ndarray]
    values: list[np.ndarray]
    rhs: list[np.ndarray]


def _pair_equations(
    a: np.ndarray, b: np.ndarray, slope: np.ndarray, step: float, first: int
) -> _Equations:
    """One direction's equations, numbered from ``first``: for each pair of valid
    neighbours (unknowns ``a`` then ``b``), ``h_b - h_a = slope · step`` (the ``b``
    entries first, then the ``a`` ones)."""
    pair = (a >= 0) & (b >= 0)
    count = int(pair.sum())
    equation = np.arange(first, first + count)
    return _Equations(
        rows=[equation, equation],
        cols=[b[pair], a[pair]],
        values=[np.full(count, 1.0), np.full(count, -1.0)],
        rhs=[slope[pair] * step],
    )


def _frankot_chellappa(gx: np.ndarray, gz: np.ndarray, dx: float, dz: float) -> np.ndarray:
    """The height whose gradient is nearest ``(gx, gz)`` among periodic ones, on the
    field mirrored about both edges (``gx`` odd across a column flip and even across a row
    flip, ``gz`` the other way round): ``ĥ = -i (ω_x ĝx + ω_z ĝz) / (ω_x² + ω_z²)``."""
    p = np.block([[gx, -gx[:, ::-1]], [gx[::-1, :], -gx[::-1, ::-1]]])
    q = np.block([[gz, gz[:, ::-1]], [-gz[::-1, :], -gz[::-1, ::-1]]])
    wx = 2.0 * np.pi * np.fft.fftfreq(p.shape[1], dx)[None, :]
    wz = 2.0 * np.pi * np.fft.fftfreq(p.shape[0], dz)[:, None]
    denominator = wx**2 + wz**2
    denominator[0, 0] = 1.0
    spectrum = -1j * (wx * np.fft.fft2(p) + wz * np.fft.fft2(q)) / denominator
    spectrum[0, 0] = 0.0
    return np.asarray(np.fft.ifft2(spectrum).real[: gx.shape[0], : gx.shape[1]])


def remove_plane(
    heights: np.ndarray, outside: np.ndarray | None = None, regions: np.ndarray | None = None
) -> np.ndarray:
    """``heights`` minus the plane ``a + b column + c row`` fitted (least squares) to its
    finite values where ``outside`` (default: all of them). With ``regions`` (an integer
    label per pixel, as :func:`scipy.ndimage.label` gives), the tilt is shared and each
    region gets its own offset ``a`` (regions unconnected to each other have unrelated
    offsets); a region with no pixel to fit keeps its heights' offset."""
    fit = np.isfinite(heights)
    if outside is not None:
        fit &= np.asarray(outside, bool)
    if fit.sum() < 3:
        return heights
    grid = np.indices(heights.shape)
    all_rows, all_cols = grid[0], grid[1]
    labels: np.ndarray = np.zeros(heights.shape, int)
    if regions is not None:
        labels = np.unique(np.asarray(regions), return_inverse=True)[1].reshape(heights.shape)
    count = int(labels.max()) + 1

    def design(where: np.ndarray) -> np.ndarray:
        offsets = np.zeros((int(where.sum()), count))
        offsets[np.arange(len(offsets)), labels[where]] = 1.0
        return np.column_stack([offsets, all_cols[where], all_rows[where]])

    coef = np.linalg.lstsq(design(fit), heights[fit], rcond=None)[0]
    finite = np.isfinite(heights)
    result = heights.copy()
    result[finite] -= design(finite) @ coef
    return result


@dataclass(frozen=True)
class Dent:
    """A Gaussian dent fitted to a height map: ``depth`` (positive for a dent, the map's
    unit), ``sigma_mm`` (its isotropic σ) and centre ``(x0, z0)`` mm."""

    depth: float
    sigma_mm: float
    x0_mm: float
    z0_mm: float


def dent_from_height(height: np.ndarray, x_mm: np.ndarray, z_mm: np.ndarray) -> Dent:
    """The isotropic Gaussian ``-depth exp(-r²/2σ²) + c`` that fits ``height`` (finite
    values; SciPy's ``curve_fit``), started from the map's lowest point."""
    from scipy.optimize import curve_fit

    height, x_mm, z_mm = (np.asarray(a, np.float64) for a in (height, x_mm, z_mm))
    ok = np.isfinite(height)
    if ok.sum() < 5:
        raise GlshadeError("dent_from_height: fewer than 5 valid heights")
    h, x, z = height[ok], x_mm[ok], z_mm[ok]

    def model(
        xz: tuple[np.ndarray, np.ndarray],
        depth: float,
        sigma: float,
        x0: float,
        z0: float,
        level: float,
    ) -> np.ndarray:
        px, pz = xz
        return level - depth * np.exp(-((px - x0) ** 2 + (pz - z0) ** 2) / (2.0 * sigma**2))

    import warnings

    from scipy.optimize import OptimizeWarning

    lowest = int(np.argmin(h))
    extent = max(np.ptp(x), np.ptp(z), 1e-9)
    start = (
        float(np.median(h) - h[lowest]),
        0.1 * extent,
        x[lowest],
        z[lowest],
        float(np.median(h)),
    )
    with warnings.catch_warnings():  # the fit's covariance is not what is asked for
        warnings.simplefilter("ignore", OptimizeWarning)
        params, _ = curve_fit(model, (x, z), h, p0=start, maxfev=5000)
    depth, sigma, x0, z0, _ = params
    return Dent(float(depth), float(abs(sigma)), float(x0), float(z0))
