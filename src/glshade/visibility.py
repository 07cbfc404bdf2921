"""Defect visibility: the paper's contour metric (SPEC §6) and its continuous companion.

The paper's metric, in OpenCV, for one pair of images (no defect / defect) at one phase:

1. binarise both (default: radiance > 0.5 of the emitter peak; Otsu as an option);
2. keep the central columns (default: the central half), cutting the stripe contours at
   fixed columns;
3. register the defect image onto the normal one (the whole-pixel shift within a few
   pixels that best correlates the contour images; reported and applied; zero for
   rendered pairs);
4. label the white stripes (connected components) and pair them **by identity**: a
   stripe of one image is the partner of the stripe of the other image that occupies
   the same rows at a cut column (the defect does not reach the cut ends), or, for a
   stripe that touches no cut column, that covers essentially the same pixels; never
   of whichever stripe happens to be nearest;
5. the distance between partners: every top (bottom) edge of a stripe, compared with
   the nearest top (bottom) edge of its partner in the same column, both ways; the
   largest such shift over all partners, in pixels, is the visibility at this phase.

:func:`paper_visibility` repeats this over phase shifts of ``step_mm`` across one period
and keeps the maximum (SPEC §6 step 7). Stripes with no partner (islands that a fold of
the stripe map cuts out of a stripe) are counted, never silently measured.

The continuous metric (:func:`continuous_visibility`) works on the emitter maps ``v0``
(no defect) and ``v1`` (defect): for each pixel ``r`` of a kept column, the row ``r0``
where ``v0(r0) = v1(r)``; the displacement is ``|r - r0|`` pixels. It is the paper's
metric in the limit of a vanishing phase step and no pixel quantisation.

Everything here works on NumPy arrays; nothing needs a GL context.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import cv2
import numpy as np

from .errors import GlshadeError
from .scene import Emitter


@dataclass(frozen=True)
class MetricSettings:
    """``threshold``: binarisation level as a fraction of the emitter peak (0, 1);
    ``otsu``: use Otsu's threshold per image instead; ``keep_fraction``: the central
    fraction of the columns kept (0, 1]; ``step_mm``: phase step of the sweep (mm);
    ``max_offset_px``: the registration's search radius (pixels); ``min_period_px``:
    pixels where the defect-free stripe period spans fewer pixels than this are left
    out of the contours (see :func:`resolved_mask`; 0 keeps every pixel)."""

    threshold: float = 0.5
    otsu: bool = False
    keep_fraction: float = 0.5
    step_mm: float = 0.25
    max_offset_px: int = 8
    min_period_px: float = 4.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.threshold) and 0.0 < self.threshold < 1.0):
            raise GlshadeError(f"threshold: must be in (0, 1) of the emitter peak, got {self.threshold}")
        if not (math.isfinite(self.keep_fraction) and 0.0 < self.keep_fraction <= 1.0):
            raise GlshadeError(f"keep_fraction: must be in (0, 1], got {self.keep_fraction}")
        if not (math.isfinite(self.step_mm) and self.step_mm > 0.0):
            raise GlshadeError(f"step: must be a number of mm > 0, got {self.step_mm}")

        if not (math.isfinite(self.min_period_px) and self.min_period_px >= 0.0):
            raise GlshadeError(f"min_period_px: must be a number of pixels >= 0, got {self.min_period_px}")

    def phases(self, period_mm: float) -> np.ndarray:
        """Phase shifts of the sweep: 0, step, 2 step, … below one period (a shift of a
        whole period reproduces phase 0). A step larger than the period is an error."""
        if self.step_mm > period_mm:
            raise GlshadeError(f"step: must be at most one stripe period ({period_mm:g} mm), got {self.step_mm:g} mm")
        count = max(1, math.ceil(period_mm / self.step_mm - 1e-9))
        return np.arange(count) * self.step_mm


def kept_columns(width: int, keep_fraction: float) -> slice:
    """The central ``keep_fraction`` of ``width`` columns (SPEC §6 step 3)."""
    keep = max(2, round(width * keep_fraction))
    start = (width - keep) // 2
    return slice(start, start + keep)


# --------------------------------------------------------------------------- shading
def stripe_radiance(v: np.ndarray, emitter: Emitter, phase_mm: float) -> np.ndarray:
    """Mirror radiance ``L(v)`` of SPEC §3 (float32; 0 where ``v`` is NaN).

    The same sum as the shader: every stripe within 10 σ of ``v``.
    """
    period, sigma = emitter.period, emitter.sigma_mm
    w = (np.asarray(v, np.float64) - phase_mm) / period
    w -= np.round(w)
    reach = math.ceil(10.0 * sigma / period) + 1
    total = np.zeros(w.shape)
    scale = period / sigma
    for k in range(-reach, reach + 1):
        total += np.exp(-0.5 * ((w - k) * scale) ** 2)
    return np.nan_to_num(total, nan=0.0).astype(np.float32)


def stripe_half_width(emitter: Emitter, threshold: float) -> float | None:
    """Half-width ``w*`` (mm) of the region ``L > threshold`` around a stripe centre.

    ``L`` is periodic and even; when it decreases monotonically from a stripe's centre
    to the middle between stripes (true for every stripe narrower than about a third of
    the period), ``L(v) > threshold`` is exactly ``|v - phase - k period| < w*`` for the
    nearest ``k``: a binarisation without evaluating a single exponential. Returns
    ``None`` when that does not hold (use :func:`stripe_radiance`), ``0`` when no point
    is above the threshold and ``period / 2`` when every point is.
    """
    period = emitter.period
    grid = np.linspace(0.0, 0.5 * period, 2049)
    level = stripe_radiance(grid, emitter, 0.0).astype(np.float64)
    if np.any(np.diff(level) > 1e-12):
        return None
    if level[0] <= threshold:
        return 0.0
    if level[-1] > threshold:
        return 0.5 * period
    lo, hi = 0.0, 0.5 * period
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if float(stripe_radiance(np.array([mid]), emitter, 0.0)[0]) > threshold:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def resolved_mask(v0: np.ndarray, period_mm: float, min_period_px: float) -> np.ndarray:
    """Pixels where the sensor resolves the stripes: the defect-free map's local period,
    ``period / |grad v0|`` (pixels), is at least ``min_period_px``.

    Where stripes are narrower than a couple of pixels (near a silhouette, at grazing
    views of curved surfaces) the binarised pattern aliases: sub-pixel changes make
    thin stripes touch diagonally or vanish, so contours change identity and the paper's
    metric would measure that noise instead of the defect. Those pixels are left out of
    both images alike.
    """
    gy, gx = np.gradient(np.asarray(v0, np.float64))
    with np.errstate(invalid="ignore", divide="ignore"):
        local_period = period_mm / np.hypot(gx, gy)
    return np.isfinite(local_period) & (local_period >= min_period_px)


def binarize_v(v: np.ndarray, emitter: Emitter, phase_mm: float, half_width_mm: float) -> np.ndarray:
    """``L(v) > threshold`` from the uv map, given :func:`stripe_half_width` (bool)."""
    w = (v - phase_mm) / emitter.period
    with np.errstate(invalid="ignore"):
        w -= np.round(w)
        return np.abs(w) < half_width_mm / emitter.period


def binarize(image: np.ndarray, settings: MetricSettings) -> np.ndarray:
    """Binarise a radiance image: ``> threshold`` of the peak (1), or Otsu's level."""
    if settings.otsu:
        pixels = np.clip(np.nan_to_num(image) * 255.0 + 0.5, 0, 255).astype(np.uint8)
        _, binary = cv2.threshold(pixels, 0, 255, cv2.THRESH_BINARY | cv2.THRESH_OTSU)
        return binary > 0
    return np.nan_to_num(image) > settings.threshold


def contour_image(binary: np.ndarray) -> np.ndarray:
    """The stripe contours of a binary image: white pixels with a black 4-neighbour (uint8 0/255)."""
    white = binary.astype(np.uint8)
    inner = cv2.erode(white, np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], np.uint8), borderType=cv2.BORDER_REPLICATE)
    return ((white > 0) & (inner == 0)).astype(np.uint8) * 255


# --------------------------------------------------------------------------- contours
@dataclass(frozen=True)
class Stripes:
    """The white stripes of one cut binary image: labels and their contour pixels.

    A stripe's contours are its top edges (first row of a run of the stripe in a
    column) and its bottom edges (last row of a run). They are kept as sorted keys
    ``(label * width + column) * height + row``, so the edges of one stripe in one
    column are a contiguous, sorted slice. Label 0 is the background.
    """

    labels: np.ndarray
    count: int
    top_keys: np.ndarray
    bottom_keys: np.ndarray


def find_stripes(binary_cut: np.ndarray) -> Stripes:
    """Label the white stripes (8-connected) and collect their top and bottom edges."""
    count, labels = cv2.connectedComponents(binary_cut.astype(np.uint8), connectivity=8, ltype=cv2.CV_32S)
    height, width = labels.shape

    def keys(edge: np.ndarray) -> np.ndarray:
        rows, cols = np.nonzero(edge)
        return np.sort((labels[rows, cols].astype(np.int64) * width + cols) * height + rows)

    starts = labels > 0
    starts[1:] &= labels[1:] != labels[:-1]
    ends = labels > 0
    ends[:-1] &= labels[:-1] != labels[1:]
    return Stripes(labels=labels, count=count - 1, top_keys=keys(starts), bottom_keys=keys(ends))


def pair_stripes(normal: Stripes, defect: Stripes, min_iou: float = 0.5) -> tuple[np.ndarray, int]:
    """Partners by identity, never by nearness.

    1. At the cut ends: stripes that share rows at the first or the last kept column
       are partners (the defect does not reach the cut ends, SPEC §6).
    2. A stripe that touches neither cut column (an arc of a curved surface's pattern
       that enters and leaves through the image's top or bottom) is the partner of the
       stripe of the other image it overlaps most, provided they are essentially the
       same pixels (intersection over union >= ``min_iou``).

    What is left has no partner: typically islands that a fold of the stripe map cuts
    out of a stripe. Returns the pairs ``(k_normal, k_defect)`` and the number of
    stripes, in either image, without a partner.
    """
    width = normal.labels.shape[1]
    a_all, b_all = normal.labels.ravel(), defect.labels.ravel()
    na, nb = normal.count + 1, defect.count + 1
    overlap = np.bincount(a_all * nb + b_all, minlength=na * nb).reshape(na, nb)
    pairs = set()
    for column in (0, width - 1):
        a, b = normal.labels[:, column], defect.labels[:, column]
        both = (a > 0) & (b > 0)
        pairs.update(zip(a[both].tolist(), b[both].tolist()))
    paired_a = {p[0] for p in pairs}
    paired_b = {p[1] for p in pairs}
    area_a, area_b = overlap.sum(axis=1), overlap.sum(axis=0)
    inner = overlap[1:, 1:]
    if inner.size:
        for kb in range(1, nb):
            if kb in paired_b:
                continue
            ka = int(np.argmax(inner[:, kb - 1])) + 1
            common = overlap[ka, kb]
            if common and common / (area_a[ka] + area_b[kb] - common) >= min_iou:
                pairs.add((ka, kb))
        paired_a = {p[0] for p in pairs}
        paired_b = {p[1] for p in pairs}
    unpaired = (normal.count - len(paired_a)) + (defect.count - len(paired_b))
    joined = np.array(sorted(pairs), np.int64).reshape(-1, 2)
    return joined, int(unpaired)


def _nearest_in_group(target: np.ndarray, query: np.ndarray, height: int) -> np.ndarray:
    """For each query key, the distance (rows) to the nearest target key of the same
    (label, column) group; inf where that group has none. ``target`` is sorted."""
    if target.size == 0:
        return np.full(query.shape, np.inf)
    idx = np.searchsorted(target, query)
    group = query // height
    best = np.full(query.shape, np.inf)
    for cand in (idx - 1, idx):
        inside = (cand >= 0) & (cand < target.size)
        cand = np.clip(cand, 0, target.size - 1)
        same = inside & (target[cand] // height == group)
        best = np.minimum(best, np.where(same, np.abs(target[cand] - query), np.inf))
    return best


def _edge_shift(source: np.ndarray, target: np.ndarray, partner: dict[int, list[int]], labels: int, shape: tuple[int, int]) -> float:
    """Largest distance (rows) from an edge of a stripe in ``source`` to the nearest edge
    of the same kind of its partner stripe in ``target``, in the same column."""
    height, width = shape
    if source.size == 0 or target.size == 0:
        return 0.0
    plane = width * height
    label = source // plane
    rest = source % plane
    single = np.full(labels + 1, -1, np.int64)  # stripes with one partner: all at once
    for own, others in partner.items():
        if len(others) == 1:
            single[own] = others[0]
    mate = single[label]
    chosen = mate >= 0
    best = _nearest_in_group(target, mate[chosen] * plane + rest[chosen], height)
    worst = float(best[np.isfinite(best)].max()) if np.isfinite(best).any() else 0.0
    for own, others in partner.items():  # split or merged stripes: the nearest of their partners
        if len(others) < 2:
            continue
        mine = rest[label == own]
        near = np.min([_nearest_in_group(target, other * plane + mine, height) for other in others], axis=0)
        if np.isfinite(near).any():
            worst = max(worst, float(near[np.isfinite(near)].max()))
    return worst


def paired_distance(normal: Stripes, defect: Stripes, pairs: np.ndarray) -> float:
    """Largest shift (px) between corresponding contours: every top (bottom) edge of a
    stripe is compared with the nearest top (bottom) edge of its partner stripe in the
    same column, both ways; edges of other stripes never count (identity, not
    nearness). Columns where the two images agree contribute exactly 0."""
    if len(pairs) == 0:
        return 0.0
    a_to_b: dict[int, list[int]] = {}
    b_to_a: dict[int, list[int]] = {}
    for a, b in pairs.tolist():
        a_to_b.setdefault(a, []).append(b)
        b_to_a.setdefault(b, []).append(a)
    shape = normal.labels.shape
    return max(
        _edge_shift(normal.top_keys, defect.top_keys, a_to_b, normal.count, shape),
        _edge_shift(defect.top_keys, normal.top_keys, b_to_a, defect.count, shape),
        _edge_shift(normal.bottom_keys, defect.bottom_keys, a_to_b, normal.count, shape),
        _edge_shift(defect.bottom_keys, normal.bottom_keys, b_to_a, defect.count, shape),
    )


def register(normal_binary_cut: np.ndarray, defect_binary_cut: np.ndarray, max_offset_px: int = 8) -> tuple[int, int]:
    """Whole-pixel offset ``(dx, dy)`` that moves the defect image onto the normal one
    (SPEC §6 step 4): the shift within ``±max_offset_px`` that best correlates their
    contour images (normalised cross-correlation); among equally good shifts the
    smallest wins, so a pattern that is blind to a direction (horizontal stripes are
    blind to horizontal shifts) is not moved along it. Zero for rendered pairs.

    Phase correlation is not used: on a periodic stripe pattern its peak is ambiguous
    up to whole periods.
    """
    a = contour_image(normal_binary_cut).astype(np.float32)
    b = contour_image(defect_binary_cut).astype(np.float32)
    m = max_offset_px
    h, w = a.shape
    if not a.any() or not b.any() or h <= 2 * m + 1 or w <= 2 * m + 1:
        return 0, 0
    template = b[m : h - m, m : w - m]
    if not template.any():
        return 0, 0
    score = cv2.matchTemplate(a, template, cv2.TM_CCORR_NORMED)  # (2m+1, 2m+1), offset (x, y) - m
    best = float(score.max())
    ys, xs = np.nonzero(score >= best - 1e-6)
    k = int(np.argmin((xs - m) ** 2 + (ys - m) ** 2))
    return int(xs[k] - m), int(ys[k] - m)


def shift_image(binary: np.ndarray, dx: int, dy: int) -> np.ndarray:
    """Move a binary image by whole pixels (vacated pixels are black)."""
    if dx == 0 and dy == 0:
        return binary
    out = np.zeros_like(binary)
    h, w = binary.shape
    src = binary[max(0, -dy) : h - max(0, dy), max(0, -dx) : w - max(0, dx)]
    out[max(0, dy) : max(0, dy) + src.shape[0], max(0, dx) : max(0, dx) + src.shape[1]] = src
    return out


@dataclass(frozen=True)
class PhaseResult:
    """The metric at one phase: ``distance_px`` between partner contours, the number of
    ``unpaired`` stripes, and the number of ``pairs``."""

    phase_mm: float
    distance_px: float
    unpaired: int
    pairs: int


def compare_binaries(
    normal_binary: np.ndarray,
    defect_binary: np.ndarray,
    columns: slice,
    offset: tuple[int, int] = (0, 0),
    normal_stripes: Stripes | None = None,
    phase_mm: float = 0.0,
) -> PhaseResult:
    """Steps 3–5 of the metric for one phase (binaries of the full width; ``columns``
    selects the kept ones; ``offset`` is applied to the defect image)."""
    defect = shift_image(defect_binary, *offset)
    normal_stripes = normal_stripes or find_stripes(normal_binary[:, columns])
    defect_stripes = find_stripes(defect[:, columns])
    pairs, unpaired = pair_stripes(normal_stripes, defect_stripes)
    return PhaseResult(phase_mm, paired_distance(normal_stripes, defect_stripes, pairs), unpaired, len(pairs))


@dataclass(frozen=True)
class Visibility:
    """The paper's metric over a phase sweep.

    ``visibility_px``: the largest contour shift; ``best_phase_mm``: where it was
    reached; ``offset_px``: the registration offset (dx, dy), whole pixels, found at
    phase 0 and applied to the defect image at every phase;
    ``unpaired_contours``: stripes without a partner at the best phase (the largest
    over the sweep in ``max_unpaired``); ``images``: (normal, defect) radiance or
    binary images at the best phase, as the caller provided them.
    """

    visibility_px: float
    best_phase_mm: float
    offset_px: tuple[int, int]
    unpaired_contours: int
    max_unpaired: int
    per_phase: list[PhaseResult] = field(default_factory=list)
    images: tuple[np.ndarray, np.ndarray] | None = None


def paper_visibility(
    binaries: Callable[[float], tuple[np.ndarray, np.ndarray]],
    period_mm: float,
    settings: MetricSettings = MetricSettings(),
    images: Callable[[float], tuple[np.ndarray, np.ndarray]] | None = None,
    normal_cache: dict | None = None,
    resolved: np.ndarray | None = None,
) -> Visibility:
    """SPEC §6 steps 1–7. ``binaries(phase)`` returns the (normal, defect) binary images
    at a phase; ``images(phase)`` (optional) the images to keep for the best phase.
    ``normal_cache`` (a dict) lets several defects share the normal image's analysis.
    ``resolved`` (bool, optional): pixels outside it are black in both binaries
    (:func:`resolved_mask`)."""
    phases = settings.phases(period_mm)
    if resolved is not None:
        plain = binaries

        def binaries(phase: float) -> tuple[np.ndarray, np.ndarray]:
            normal, defect = plain(phase)
            return normal & resolved, defect & resolved

    normal0, defect0 = binaries(float(phases[0]))
    columns = kept_columns(normal0.shape[1], settings.keep_fraction)
    offset = register(normal0[:, columns], defect0[:, columns], settings.max_offset_px)
    results = []
    for phase in phases:
        normal, defect = (normal0, defect0) if phase == phases[0] else binaries(float(phase))
        stripes = None
        if normal_cache is not None:
            key = (float(phase), columns.start, columns.stop)
            stripes = normal_cache.get(key)
            if stripes is None:
                stripes = normal_cache[key] = find_stripes(normal[:, columns])
        results.append(compare_binaries(normal, defect, columns, offset, stripes, float(phase)))
    best = max(results, key=lambda r: r.distance_px)
    return Visibility(
        visibility_px=best.distance_px,
        best_phase_mm=best.phase_mm,
        offset_px=offset,
        unpaired_contours=best.unpaired,
        max_unpaired=max(r.unpaired for r in results),
        per_phase=results,
        images=images(best.phase_mm) if images is not None else None,
    )


def image_visibility(
    normal_images: Callable[[float], np.ndarray],
    defect_images: Callable[[float], np.ndarray],
    period_mm: float,
    settings: MetricSettings = MetricSettings(),
) -> Visibility:
    """The paper's metric on radiance images (any source: renders, photos, synthetic),
    binarised with ``settings``."""

    def binaries(phase: float) -> tuple[np.ndarray, np.ndarray]:
        return binarize(normal_images(phase), settings), binarize(defect_images(phase), settings)

    return paper_visibility(
        binaries, period_mm, settings, images=lambda p: (normal_images(p), defect_images(p))
    )


# --------------------------------------------------------------------------- continuous
@dataclass(frozen=True)
class Continuous:
    """``visibility_px``: largest displacement; ``displacement_px``: the map (NaN outside
    the kept columns or where undefined); ``folded``: the defect's emitter map folds
    (``v1`` is not monotonic along some kept column)."""

    visibility_px: float
    displacement_px: np.ndarray
    folded: bool


def continuous_visibility(v0: np.ndarray, v1: np.ndarray, keep_fraction: float = 0.5) -> Continuous:
    """SPEC §6 continuous companion metric from the emitter maps (mm, NaN = no hit)."""
    height, width = v0.shape
    columns = kept_columns(width, keep_fraction)
    displacement = np.full((height, width), np.nan)
    rows = np.arange(height, dtype=np.float64)
    folded = False
    for j in range(columns.start, columns.stop):
        a, b = v0[:, j].astype(np.float64), v1[:, j].astype(np.float64)
        valid = np.isfinite(a)
        if valid.sum() < 2:
            continue
        ra, va = rows[valid], a[valid]
        step = np.diff(va)
        if not (np.all(step > 0) or np.all(step < 0)):
            # the defect-free map should be monotonic; keep its longest monotonic run
            keep = _longest_monotonic(va)
            ra, va = ra[keep], va[keep]
        if va[0] > va[-1]:
            ra, va = ra[::-1], va[::-1]
        good = np.isfinite(b) & (b >= va[0]) & (b <= va[-1])
        if good.any():
            r0 = np.interp(b[good], va, ra)
            displacement[good, j] = np.abs(rows[good] - r0)
        fb = b[np.isfinite(b)]
        if fb.size > 2:
            d = np.diff(fb)
            d = d[d != 0]
            folded |= bool(d.size and np.any(np.sign(d) != np.sign(d[0])))
    value = float(np.nanmax(displacement)) if np.isfinite(displacement).any() else 0.0
    return Continuous(visibility_px=value, displacement_px=displacement, folded=folded)


def _longest_monotonic(values: np.ndarray) -> slice:
    sign = np.sign(np.diff(values))
    best, start = (0, 1), 0
    for i in range(1, len(sign) + 1):
        if i == len(sign) or sign[i] != sign[start] or sign[i] == 0:
            if i - start > best[1] - best[0]:
                best = (start, i + 1)
            start = i
    return slice(*best)


# --------------------------------------------------------------------------- pictures
def overlay(normal_binary: np.ndarray, defect_binary: np.ndarray, keep_fraction: float = 0.5) -> np.ndarray:
    """Fig. 9 of the paper: contours of the cut images, normal in blue, defect in red,
    overlap in magenta, on black (uint8 RGB, the kept columns only)."""
    columns = kept_columns(normal_binary.shape[1], keep_fraction)
    a = contour_image(normal_binary[:, columns]) > 0
    b = contour_image(defect_binary[:, columns]) > 0
    rgb = np.zeros(a.shape + (3,), np.uint8)
    rgb[a, 2] = 255
    rgb[b, 0] = 255
    return rgb
