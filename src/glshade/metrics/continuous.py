"""The metric's two continuous numbers, from the emitter maps ``v0`` (no defect) and
``v1`` (defect), in pixels of the image.

- :func:`deflection`: for each pixel ``r`` of a kept column, the row ``r0`` where
  ``v0(r0) = v1(r)``; ``deflection_px`` is the largest ``|r - r0|``. It says how far the
  dent turns the rays, whether or not a viewer sees a bent contour. It also finds where
  the map **folds**: where ``v1`` runs against ``v0`` along a column.
- :func:`visibility_limit`: the limit of the paper's contour metric for a vanishing phase
  step and pixel size, with the same contour rules (outermost crossing per column, islands
  excluded, identity of stripes). Where nothing folds, every stripe edge crosses each
  column once and moves by the displacement there, so the limit is the largest
  displacement. Where the map folds, it is computed: in a window around the folded
  columns the maps are interpolated (cubic, ``upsample`` rows per pixel row), the stripes
  are binarised at a fine set of phases, each stripe is labelled by its index ``k`` on the
  emitter (so no two stripes can merge), the pieces that reach the window's edge are the
  stripe (pieces that do not are islands), and the outermost crossings are located between
  samples by linear interpolation of ``v``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class Deflection:
    """``displacement_px``: ``|r - r0|`` per pixel (float32, H×W; NaN outside the kept
    columns or where ``v1`` leaves the column's range of ``v0``); ``deflection_px``: its
    largest value; ``fold_columns``: image columns (kept) where ``v1`` runs against ``v0``;
    ``folded``: there is at least one."""

    displacement_px: np.ndarray
    deflection_px: float
    fold_columns: np.ndarray

    @property
    def folded(self) -> bool:
        return len(self.fold_columns) > 0


@dataclass(frozen=True)
class ColumnOrder:
    """How the defect-free map runs down each kept column, once per geometry: ``direction``
    (+1 increasing, -1 decreasing, 0 otherwise: with no-hit pixels or a turn), the rows per
    mm of ``v`` beside each pixel (``rows_per_mm``: the larger of its two neighbouring
    segments, inf where a segment is flat) and the pixels (``far``, flat indices of the
    cut map) that a move of any size may carry far: those outside the longest monotonic
    run of a column that turns."""

    direction: np.ndarray
    rows_per_mm: np.ndarray
    far: np.ndarray
    zeros: np.ndarray
    runs: dict[int, tuple[np.ndarray, np.ndarray]]


def column_order(v0_cut: np.ndarray) -> ColumnOrder:
    """:class:`ColumnOrder` of a cut defect-free map."""
    a = np.asarray(v0_cut, np.float64)
    direction = _monotone_direction(a)
    with np.errstate(divide="ignore", invalid="ignore"):
        gaps = np.diff(a, axis=0)
        step = 1.0 / np.abs(gaps)
    per_mm = np.full(a.shape, np.nan)
    per_mm[1:] = step
    per_mm[:-1] = np.fmax(per_mm[:-1], step)  # NaN (no hit) beside a pixel is ignored
    finite = np.isfinite(a)
    count = finite.sum(axis=0)
    first = np.argmax(finite, axis=0)
    last = a.shape[0] - 1 - np.argmax(finite[::-1], axis=0)
    with np.errstate(invalid="ignore"):
        rising, falling = (gaps > 0).sum(axis=0), (gaps < 0).sum(axis=0)
    simple = (count >= 2) & (last - first + 1 == count)
    simple &= (rising == count - 1) | (falling == count - 1)
    far = []
    for j in np.nonzero(~simple & (count >= 2))[0]:  # holes or a turn: row by row
        per_mm[:, j], outside = _turning_column(a[:, j])
        far.append(outside * a.shape[1] + j)
    per_mm[np.isnan(per_mm)] = 0.0
    return ColumnOrder(
        direction=direction,
        rows_per_mm=per_mm.astype(np.float32),
        far=np.concatenate(far).astype(np.int64) if far else np.empty(0, np.int64),
        zeros=np.where(finite, 0.0, np.nan).astype(np.result_type(v0_cut.dtype, np.float32)),
        runs={int(j): run for j in np.nonzero(direction == 0)[0] if (run := _run_of(a, int(j)))},
    )


def _run_of(v0: np.ndarray, j: int) -> tuple[np.ndarray, np.ndarray] | None:
    """A column that is not monotone read as :func:`_inverse_turning` reads it: the rows
    and values of its finite pixels (their longest monotonic run where it turns), ``v``
    increasing; None where fewer than two pixels see the emitter."""
    every = np.arange(v0.shape[0], dtype=np.float64)
    valid = np.isfinite(v0[:, j])
    if valid.sum() < 2:
        return None
    ra, va = every[valid], v0[valid, j]
    step = np.diff(va)
    if not (np.all(step > 0) or np.all(step < 0)):
        keep = _longest_monotonic(va)  # the defect-free map should be monotonic
        ra, va = ra[keep], va[keep]
    if va[0] > va[-1]:
        ra, va = ra[::-1], va[::-1]
    return ra, va


def _turning_column(column: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows per mm beside each pixel of a column whose finite pixels have holes or turn
    (between its finite neighbours in their longest monotonic run, as the inverse reads
    it), and the rows outside that run."""
    rows = np.arange(len(column))
    valid = np.isfinite(column)
    ra, va = rows[valid], column[valid]
    run = slice(0, len(va))
    gaps = np.diff(va)
    if not (np.all(gaps > 0) or np.all(gaps < 0)):
        run = _longest_monotonic(va)
    outside = np.ones(len(va), bool)
    outside[run] = False
    ra, va = ra[run], va[run]
    with np.errstate(divide="ignore", invalid="ignore"):
        local = np.diff(ra) / np.abs(np.diff(va))
    beside = np.zeros(len(va))
    beside[1:] = local
    beside[:-1] = np.fmax(beside[:-1], local)
    per_mm = np.full(len(column), np.nan)
    per_mm[ra] = beside
    return per_mm, rows[valid][outside]


@dataclass(frozen=True)
class Focus:
    """Where the dent's continuous numbers are computed (cut-map coordinates): the
    ``pixels`` searched (flat indices); the ``box`` outside which the dent moves the map so
    little that it can turn a column only where ``fold_pairs`` (flat indices ``r * width +
    c`` of row pairs (r, r + 1)) say the defect-free map is nearly flat. Every pixel not
    searched is displaced by at most ``bound_px`` (its displacement map reads 0 there)."""

    box: tuple[slice, slice]
    pixels: np.ndarray
    fold_pairs: np.ndarray
    bound_px: float


def deflection(
    v0: np.ndarray,
    v1: np.ndarray,
    columns: slice,
    focus: Focus | None = None,
    order: ColumnOrder | None = None,
) -> Deflection:
    """The displacement map (``deflection_px``, docs/study.md) and the folded columns.

    Only pixels where ``v1`` differs from ``v0`` need a search: elsewhere ``r0 = r``. With a
    ``focus`` only its box and pixels are searched (the rest reads 0): the caller checks
    that its ``bound_px`` lies below what was found. ``order``: the defect-free map's
    :func:`column_order` (its directions are found here when not given).
    """
    height, width = v0.shape
    dtype = np.result_type(
        v0.dtype, v1.dtype, np.float32
    )  # fp32 maps stay fp32: more bits would be noise
    a = np.asarray(v0[:, columns], dtype)
    b = np.asarray(v1[:, columns], dtype)
    displacement = np.full((height, width), np.nan, np.float32)
    out = np.full(a.shape, np.nan, dtype)
    direction = order.direction if order is not None else _monotone_direction(a)
    if focus is None:
        out[np.isfinite(a) & (a == b)] = 0.0
        targets = np.flatnonzero(np.isfinite(b) & ~(a == b))
        folds = _against(a, b)
    else:
        out = (
            np.array(order.zeros, dtype)
            if order is not None
            else np.where(np.isfinite(a), 0.0, np.nan).astype(dtype)
        )
        targets = _focus_targets(a, b, focus, out)
        folds = _focus_folds(a, b, focus)
    rows, cols = np.divmod(targets, a.shape[1])
    smooth = direction[cols] != 0
    _inverse_regular(a, b, rows[smooth], cols[smooth], direction.astype(dtype), out)
    _inverse_turning(a, b, rows[~smooth], cols[~smooth], out, order.runs if order else None)
    value = float(np.nanmax(out)) if np.isfinite(out).any() else 0.0
    displacement[:, columns] = out
    return Deflection(displacement, value, folds + columns.start)


def _focus_targets(a: np.ndarray, b: np.ndarray, focus: Focus, out: np.ndarray) -> np.ndarray:
    """Flat indices of the changed pixels of the focus (``out`` reset there as the full
    search would find it: NaN, 0 where unchanged)."""
    pixels = focus.pixels
    pa, pb = a.ravel()[pixels], b.ravel()[pixels]
    out.ravel()[pixels] = np.where(np.isfinite(pa) & (pa == pb), 0.0, np.nan)
    return pixels[np.isfinite(pb) & ~(pa == pb)]  # a pixel listed twice is found twice alike


def _focus_folds(a: np.ndarray, b: np.ndarray, focus: Focus) -> np.ndarray:
    """:func:`_against` over the focus: its box (with the row pairs across its edges) and
    the row pairs outside where the defect-free map is flat enough to turn."""
    rows, cols = focus.box
    grown = slice(max(rows.start - 1, 0), min(rows.stop + 1, a.shape[0]))
    inside = _against(a[grown, cols], b[grown, cols]) + cols.start
    pairs = focus.fold_pairs
    r, c = np.divmod(pairs, a.shape[1])
    flat_a, flat_b = a.ravel(), b.ravel()
    below = (r + 1) * a.shape[1] + c
    with np.errstate(invalid="ignore"):
        turned = (flat_a[below] - flat_a[pairs]) * (flat_b[below] - flat_b[pairs]) < 0
    return np.unique(np.concatenate([inside, c[turned]])).astype(np.int64)


def _monotone_direction(v0: np.ndarray) -> np.ndarray:
    """Per column: +1 where the defect-free map is finite and strictly increasing down the
    column, -1 where strictly decreasing, 0 otherwise (those take the slower path)."""
    with np.errstate(invalid="ignore"):
        step = np.diff(v0, axis=0)
        finite = np.isfinite(v0).all(axis=0)
        up = finite & (step > 0).all(axis=0)
        down = finite & (step < 0).all(axis=0)
    return up.astype(np.float64) - down.astype(np.float64)


def _inverse_regular(
    v0: np.ndarray,
    v1: np.ndarray,
    rows: np.ndarray,
    cols: np.ndarray,
    direction: np.ndarray,
    out: np.ndarray,
) -> None:
    """``|r - r0|`` with ``v0(r0) = v1(r)`` (linear between rows) at the target pixels
    ``(rows, cols)`` of monotone columns (``direction`` ±1 per column: both maps are read
    times it, so every column increases), written into ``out``.

    The first guess steps from ``r`` along the local slope; then the segment ``[k, k+1]``
    that brackets ``v1`` is found by stepping ``k`` (a nearly linear column needs one or
    two steps) and ``r0`` interpolated inside it: the same inverse as ``np.interp`` per
    column, vectorised.
    """
    if not len(rows):
        return
    height, width = v0.shape
    flat = v0.ravel()
    sign = direction[cols]
    want = v1[rows, cols] * sign
    inside = (want >= v0[0, cols] * sign) & (want <= v0[-1, cols] * sign)
    rows, cols, want, sign = rows[inside], cols[inside], want[inside], sign[inside]
    here = flat[rows * width + cols] * sign
    below = np.clip(rows - 1, 0, height - 1)
    above = np.clip(rows + 1, 0, height - 1)
    slope = (flat[above * width + cols] * sign - flat[below * width + cols] * sign) / np.maximum(
        above - below, 1
    )
    k = np.clip(np.floor(rows + (want - here) / slope), 0, height - 2).astype(np.int64)
    active = np.arange(len(k))
    for _ in range(height):
        lo = flat[k[active] * width + cols[active]] * sign[active]
        hi = flat[(k[active] + 1) * width + cols[active]] * sign[active]
        step = (want[active] > hi).astype(np.int64) - (want[active] < lo).astype(np.int64)
        moving = step != 0
        if not moving.any():
            break
        active = active[moving]
        k[active] = np.clip(k[active] + step[moving], 0, height - 2)
    lo = flat[k * width + cols] * sign
    hi = flat[(k + 1) * width + cols] * sign
    out[rows, cols] = np.abs(rows - (k + (want - lo) / (hi - lo)))


def _inverse_turning(
    v0: np.ndarray,
    v1: np.ndarray,
    rows: np.ndarray,
    cols: np.ndarray,
    out: np.ndarray,
    runs: dict[int, tuple[np.ndarray, np.ndarray]] | None = None,
) -> None:
    """The same inverse in columns that are not monotone (no-hit pixels, a turn): per
    column, on its finite pixels, or their longest monotonic run where the column turns
    (``runs``: those of :func:`column_order`, when known)."""
    if not len(rows):
        return
    every = np.arange(v0.shape[0], dtype=np.float64)
    by_column = np.argsort(cols, kind="stable")
    rows, cols = rows[by_column], cols[by_column]
    bounds = np.flatnonzero(np.diff(cols)) + 1
    for r, j in zip(np.split(rows, bounds), cols[np.r_[0, bounds]], strict=True):
        run = runs.get(int(j)) if runs is not None else _run_of(v0, int(j))
        if run is None:
            continue
        ra, va = run
        want = v1[r, j]
        r = r[(want >= va[0]) & (want <= va[-1])]
        out[r, j] = np.abs(every[r] - np.interp(v1[r, j], va, ra))


def fold_columns(v0: np.ndarray, v1: np.ndarray, columns: slice) -> np.ndarray:
    """Image columns (among the kept ones) where ``v1`` runs against ``v0`` between two
    neighbouring rows: the stripe map folds there."""
    return _against(v0[:, columns], v1[:, columns]) + columns.start


def _against(v0: np.ndarray, v1: np.ndarray) -> np.ndarray:
    """Columns where the two maps change in opposite directions between two rows."""
    with np.errstate(invalid="ignore"):
        against = (np.diff(v0, axis=0) * np.diff(v1, axis=0)) < 0
    return np.nonzero(against.any(axis=0))[0]


def _longest_monotonic(values: np.ndarray) -> slice:
    sign = np.sign(np.diff(values))
    best, start = (0, 1), 0
    for i in range(1, len(sign) + 1):
        if i == len(sign) or sign[i] != sign[start] or sign[i] == 0:
            if i - start > best[1] - best[0]:
                best = (start, i + 1)
            start = i
    return slice(*best)


# --------------------------------------------------------------------------- the limit
@dataclass(frozen=True)
class StripeLevels:
    """Where the binarised stripes are on the emitter: stripe ``k`` at phase ``φ`` is
    ``|v - φ - k period| < half_width_mm``."""

    period_mm: float
    half_width_mm: float


@dataclass(frozen=True)
class Limit:
    """``visibility_px``: the limit of the paper's metric; ``best_phase_mm``: where it was
    reached inside the fold window (NaN when nothing folds); ``window``: the window
    ``(row0, row1, col0, col1)`` of the image that was refined, or ``None``."""

    visibility_px: float
    best_phase_mm: float = float("nan")
    window: tuple[int, int, int, int] | None = None


def visibility_limit(
    v0: np.ndarray,
    v1: np.ndarray,
    valid: np.ndarray | None,
    columns: slice,
    stripes: StripeLevels,
    moved: Deflection,
    upsample: int = 4,
    phase_samples: int = 32,
    focus: Focus | None = None,
) -> Limit:
    """``visibility_continuous_px`` (see the module docstring).

    ``valid``: pixels the contour metric may use (None: where both maps see the emitter,
    looked at only where needed); ``moved``: :func:`deflection` of the same maps;
    ``focus``: the one it was computed in (outside it the displacement is not looked at:
    the caller checks its bound).
    """
    window = None
    if moved.folded:
        window = _fold_window(v0, v1, columns, moved.fold_columns, stripes.period_mm)
    if focus is None:
        outside = np.where(_valid(v0, v1, valid), moved.displacement_px, np.nan)
        if window is not None:
            outside[window[0] : window[1], window[2] : window[3]] = np.nan
        rest = float(np.nanmax(outside)) if np.isfinite(outside).any() else 0.0
    else:
        rest = _focused_rest(v0, v1, valid, columns, moved.displacement_px, focus, window)
    if window is None:
        return Limit(rest)
    r0, r1, c0, c1 = window
    box = (slice(r0, r1), slice(c0, c1))
    inside, phase = _window_limit(
        v0[box],
        v1[box],
        _valid(v0[box], v1[box], None if valid is None else valid[box]),
        stripes,
        upsample,
        phase_samples,
    )
    return Limit(max(inside, rest), phase, window)


def _valid(v0: np.ndarray, v1: np.ndarray, valid: np.ndarray | None) -> np.ndarray:
    return np.isfinite(v0) & np.isfinite(v1) if valid is None else valid


def _focused_rest(
    v0: np.ndarray,
    v1: np.ndarray,
    valid: np.ndarray | None,
    columns: slice,
    displacement: np.ndarray,
    focus: Focus,
    window: tuple[int, int, int, int] | None,
) -> float:
    """The largest displacement at the focus's valid pixels outside the fold ``window``."""
    r, c = np.divmod(focus.pixels, columns.stop - columns.start)
    c = c + columns.start
    values = displacement[r, c]
    keep = np.isfinite(values)
    keep &= (np.isfinite(v0[r, c]) & np.isfinite(v1[r, c])) if valid is None else valid[r, c]
    if window is not None:
        r0, r1, c0, c1 = window
        keep &= ~((r >= r0) & (r < r1) & (c >= c0) & (c < c1))
    return float(values[keep].max()) if keep.any() else 0.0


#: Rows where the dent moves the emitter map by less than this (pixels) are outside the
#: fold window; there the limit takes the displacement, which is exact to this tolerance.
WINDOW_TOLERANCE_PX = 1e-3


def _fold_window(
    v0: np.ndarray, v1: np.ndarray, columns: slice, folds: np.ndarray, period_mm: float
) -> tuple[int, int, int, int]:
    """Rows and columns around the fold: the folded columns plus 3 on each side (kept
    columns only); the rows where the dent moves the map in them by more than
    :data:`WINDOW_TOLERANCE_PX`, plus a stripe period.

    Outside it every column is monotonic, so whatever reaches the window's edge is part of
    a stripe that runs on to the cut columns (islands lie inside it), and a contour there
    moves by the displacement.
    """
    c0 = max(columns.start, int(folds.min()) - 3)
    c1 = min(columns.stop, int(folds.max()) + 4)
    a, b = v0[:, c0:c1], v1[:, c0:c1]
    with np.errstate(invalid="ignore"):
        slope = float(np.nanmedian(np.abs(np.diff(a, axis=0))))
        if not (np.isfinite(slope) and slope > 0):
            slope = period_mm
        changed = np.nonzero((np.abs(b - a) > WINDOW_TOLERANCE_PX * slope).any(axis=1))[0]
    margin = int(math.ceil(period_mm / slope)) + 2
    height = v0.shape[0]
    return max(0, int(changed.min()) - margin), min(height, int(changed.max()) + margin + 1), c0, c1


#: The phase search inside a fold: after the grid, the two best phases are refined on a
#: grid ``_ZOOM`` times finer over ±1 step, then the best once more (74 evaluations with 32
#: phases). With 2 samples per row this is within 0.02 px of 8 samples per row on a
#: 512-phase grid on the paper's folded scenes (``benchmarks/limit_settings.py``).
_ZOOM = 8
_ZOOM_SEEDS = (2, 1)


def _window_limit(
    v0: np.ndarray,
    v1: np.ndarray,
    valid: np.ndarray,
    stripes: StripeLevels,
    upsample: int,
    phase_samples: int,
) -> tuple[float, float]:
    """The largest contour shift inside the fold window over a zooming phase search."""
    height, width = v0.shape
    size = (width, height * upsample)
    ok = valid & np.isfinite(v0) & np.isfinite(v1)
    fine0 = cv2.resize(
        np.where(ok, v0, 0.0).astype(np.float64), size, interpolation=cv2.INTER_CUBIC
    )
    fine1 = cv2.resize(
        np.where(ok, v1, 0.0).astype(np.float64), size, interpolation=cv2.INTER_CUBIC
    )
    fine_ok = cv2.resize(ok.astype(np.uint8), size, interpolation=cv2.INTER_NEAREST) > 0
    border = _border_of(fine_ok)

    def shift(phase: float) -> tuple[float, float]:
        a = _stripe_edges(fine0, fine_ok, border, phase, stripes)
        b = _stripe_edges(fine1, fine_ok, border, phase, stripes)
        return _edge_distance(a, b) / upsample, phase % stripes.period_mm

    step = stripes.period_mm / phase_samples
    tried = [shift(float(p)) for p in np.arange(phase_samples) * step]
    for seeds in _ZOOM_SEEDS:
        for _, centre in sorted(tried, reverse=True)[:seeds]:
            tried += [shift(centre + k * step / _ZOOM) for k in range(1 - _ZOOM, _ZOOM) if k]
        step /= _ZOOM
    return max(tried)


@dataclass(frozen=True)
class _Edges:
    """Per (stripe index - k0, column): the sub-pixel row of the stripe's upper and lower
    contour (outermost crossings of the stripe's non-island pieces; NaN-free: ±inf absent)."""

    k0: int
    upper: np.ndarray
    lower: np.ndarray


def _stripe_edges(
    v: np.ndarray, ok: np.ndarray, border: np.ndarray, phase: float, stripes: StripeLevels
) -> _Edges:
    period, half = stripes.period_mm, stripes.half_width_mm
    w = (v - phase) / period
    k = np.rint(w).astype(np.int64)
    bright = ok & (np.abs(w - k) * period < half)
    kept = np.zeros_like(bright)
    for parity in (0, 1):  # neighbouring stripes have other parities: they never merge
        mine = bright & ((k & 1) == parity)
        count, labels = cv2.connectedComponents(
            mine.astype(np.uint8), connectivity=8, ltype=cv2.CV_32S
        )
        reaches = np.zeros(count, bool)
        reaches[labels[0]] = reaches[labels[-1]] = reaches[labels[:, 0]] = reaches[
            labels[:, -1]
        ] = True
        reaches[labels[border]] = True
        reaches[0] = False
        kept |= reaches[labels]
    if not kept.any():
        return _Edges(0, np.full((0, v.shape[1]), np.inf), np.full((0, v.shape[1]), -np.inf))
    k0 = int(k[kept].min())
    index = np.where(kept, k - k0, -1)
    count = int(index.max()) + 1
    upper = _crossings(v, ok, index, kept, phase, stripes, k0, count, +1)
    lower = _crossings(v, ok, index, kept, phase, stripes, k0, count, -1)
    return _Edges(k0, upper, lower)


def _border_of(ok: np.ndarray) -> np.ndarray:
    if ok.all():
        return np.zeros_like(ok)
    return (cv2.dilate((~ok).astype(np.uint8), np.ones((3, 3), np.uint8)) > 0) & ok


def _crossings(
    v: np.ndarray,
    ok: np.ndarray,
    index: np.ndarray,
    kept: np.ndarray,
    phase: float,
    stripes: StripeLevels,
    k0: int,
    count: int,
    direction: int,
) -> np.ndarray:
    """Outermost sub-pixel crossing per (stripe, column): ``direction`` +1 for the upper
    contour (first kept pixel of the stripe from the top), -1 for the lower one."""
    height, width = v.shape
    same = np.zeros_like(kept)
    if direction > 0:
        same[1:] = kept[:-1] & (index[:-1] == index[1:])
    else:
        same[:-1] = kept[1:] & (index[1:] == index[:-1])
    rows, cols = np.divmod(np.flatnonzero(kept & ~same), width)
    outer = rows - direction
    inside = (outer >= 0) & (outer < height)
    outer_c = np.clip(outer, 0, height - 1)
    v_in, v_out = v[rows, cols], v[outer_c, cols]
    centre = phase + (index[rows, cols] + k0) * stripes.period_mm
    level = np.where(v_out > centre, centre + stripes.half_width_mm, centre - stripes.half_width_mm)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = (level - v_out) / (v_in - v_out)
    good = inside & ok[outer_c, cols] & np.isfinite(t) & (t >= 0) & (t <= 1)
    position = np.where(good, outer_c + direction * t, rows - 0.5 * direction)
    out = np.full(count * width, np.inf if direction > 0 else -np.inf)
    target = (index[rows, cols] * width + cols).astype(
        np.intp
    )  # flat indices: ufunc.at's fast path
    (np.minimum if direction > 0 else np.maximum).at(out, target, position.astype(np.float64))
    return out.reshape(count, width)


def _edge_distance(a: _Edges, b: _Edges) -> float:
    lo, hi = max(a.k0, b.k0), min(a.k0 + len(a.upper), b.k0 + len(b.upper))
    if hi <= lo:
        return 0.0
    sa, sb = slice(lo - a.k0, hi - a.k0), slice(lo - b.k0, hi - b.k0)
    best = 0.0
    for x, y in ((a.upper[sa], b.upper[sb]), (a.lower[sa], b.lower[sb])):
        both = np.isfinite(x) & np.isfinite(y)
        if both.any():
            best = max(best, float(np.abs(x[both] - y[both]).max()))
    return best
