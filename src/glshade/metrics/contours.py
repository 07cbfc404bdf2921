"""The paper's contour comparison (steps 3–5 of docs/study.md) for one pair of binarised images.

Everything here works on boolean images already cut to the kept columns: column 0 and
the last column are the cut columns. The rules, as docs/study.md draws them from the paper's
Figs. 8 and 9:

- A **stripe** is an 8-connected white component. It is a *contour-bearing* stripe when
  it touches a cut column (``CUT``) or, failing that, the border of the analysed region
  (``BORDER``: the image's top or bottom row, or a pixel next to one outside the region
  that sees the emitter and resolves the stripes). Anything else is an **island** (a piece
  a fold cut out of a stripe): counted, never measured.
- **Correspondence is identity, never nearness.** Stripes of the two images that share
  pixels at a cut column are partners (the defect does not reach the cut ends); a
  ``BORDER`` stripe partners the stripe of the other image that covers essentially the
  same pixels (intersection over union >= 0.5). Where pixelation splits one stripe or
  merges two, the partners form one *group*, compared as one stripe.
- **Distance**: per kept column, the upper contour of a group is its outermost crossing
  on its own side (the top-most pixel of the group in that column), the lower contour its
  bottom-most pixel; upper is compared with upper, lower with lower. The largest of these
  vertical distances, in pixels, is the distance at this phase.

:func:`compare` does all of it for one phase against a precomputed :class:`StripeMap`
of the defect-free image; :mod:`glshade.metrics.visibility` sweeps the phases.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

import cv2
import numpy as np

ISLAND, CUT, BORDER = 0, 1, 2
_CROSS = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], np.uint8)


@dataclass(frozen=True)
class Runs:
    """Pixels where a stripe enters (``top``) or leaves (``bottom``) a column, as
    parallel arrays ``rows``, ``cols``, ``labels``."""

    rows: np.ndarray
    cols: np.ndarray
    labels: np.ndarray


@dataclass(frozen=True)
class StripeMap:
    """The white stripes of one cut binary image.

    ``labels`` (int32, H×W, 0 = background); ``roles[label]`` is ``CUT``, ``BORDER`` or
    ``ISLAND`` (``roles[0]`` is unused); ``top``/``bottom`` are the first/last pixels of
    every run of a stripe in a column.
    """

    labels: np.ndarray
    roles: np.ndarray
    top: Runs
    bottom: Runs

    @property
    def count(self) -> int:
        return len(self.roles) - 1

    @property
    def islands(self) -> int:
        return int(np.count_nonzero(self.roles[1:] == ISLAND))

    @cached_property
    def areas(self) -> np.ndarray:
        """Pixels per label (made on first use: only overlap pairing needs it)."""
        return np.bincount(self.labels.ravel(), minlength=len(self.roles))

    def box(self, label: int) -> tuple[slice, slice]:
        """The rows and columns a stripe spans (from its runs)."""
        top, bottom = self.top.labels == label, self.bottom.labels == label
        cols = self.top.cols[top]
        return (
            slice(int(self.top.rows[top].min()), int(self.bottom.rows[bottom].max()) + 1),
            slice(int(cols.min()), int(cols.max()) + 1),
        )


def border_pixels(valid: np.ndarray) -> np.ndarray:
    """Pixels of the analysed region that touch its border: the top and bottom rows, and
    every valid pixel with a 4-neighbour outside ``valid`` (bool, H×W)."""
    valid = np.asarray(valid, bool)
    edge = np.zeros_like(valid)
    edge[0] = edge[-1] = True
    if not valid.all():
        outside = (
            cv2.dilate(
                (~valid).astype(np.uint8), _CROSS, borderType=cv2.BORDER_CONSTANT, borderValue=0
            )
            > 0
        )
        edge |= outside
    return edge & valid


def find_stripes(binary: np.ndarray, edge: np.ndarray | None = None) -> StripeMap:
    """Label the stripes of a cut binary image and give each its role.

    ``edge``: the border pixels of the analysed region (:func:`border_pixels`); default:
    the top and bottom rows only (an image with no mask, such as a photograph).
    """
    count, labels = cv2.connectedComponents(
        np.asarray(binary, np.uint8), connectivity=8, ltype=cv2.CV_32S
    )
    roles = np.full(count, ISLAND, np.uint8)
    on_edge = np.zeros(count, bool)
    if edge is None:
        on_edge[labels[0]] = on_edge[labels[-1]] = True
    else:
        on_edge[labels[edge]] = True
    roles[on_edge] = BORDER
    roles[labels[:, 0]] = CUT
    roles[labels[:, -1]] = CUT
    roles[0] = ISLAND
    white = labels > 0
    starts = white.copy()
    starts[1:] &= labels[1:] != labels[:-1]
    ends = white.copy()
    ends[:-1] &= labels[:-1] != labels[1:]
    return StripeMap(
        labels=labels, roles=roles, top=_runs(labels, starts), bottom=_runs(labels, ends)
    )


def _runs(labels: np.ndarray, mask: np.ndarray) -> Runs:
    flat = np.flatnonzero(mask)  # about 3x faster than a 2-D nonzero
    rows, cols = np.divmod(flat, labels.shape[1])
    return Runs(rows=rows, cols=cols, labels=labels.ravel()[flat])


# --------------------------------------------------------------------------- pairing
def pair_stripes(normal: StripeMap, defect: StripeMap, min_iou: float = 0.5) -> np.ndarray:
    """Partners ``(label_normal, label_defect)`` by identity (an int64 array of shape (K, 2)).

    1. ``CUT`` stripes that share a pixel at a cut column.
    2. A ``BORDER`` stripe left without a partner: the contour-bearing stripe of the other
       image that overlaps it most, if their intersection over union is >= ``min_iou``.
    Islands are never paired.
    """
    nb = defect.count + 1
    keys = []
    for column in (0, -1):
        a, b = normal.labels[:, column], defect.labels[:, column]
        both = (a > 0) & (b > 0)
        keys.append(a[both].astype(np.int64) * nb + b[both])
    cut_keys = np.unique(np.concatenate(keys))
    pairs = np.stack([cut_keys // nb, cut_keys % nb], axis=1)
    extra = _overlap_pairs(normal, defect, pairs, min_iou)
    if len(extra):
        pairs = np.unique(np.concatenate([pairs, extra]), axis=0)
    return pairs


def _overlap_pairs(
    normal: StripeMap, defect: StripeMap, pairs: np.ndarray, min_iou: float
) -> np.ndarray:
    """Pairs for ``BORDER`` stripes that no cut column paired, by overlap: each lone
    stripe is compared, inside its bounding box, with the other image's contour-bearing
    stripes."""
    found = set()
    for mine, other, paired, flip in (
        (defect, normal, pairs[:, 1], False),
        (normal, defect, pairs[:, 0], True),
    ):
        lone = np.nonzero(mine.roles == BORDER)[0]
        for label in lone[~np.isin(lone, paired)]:
            box = mine.box(int(label))
            inside = mine.labels[box] == label
            common = np.bincount(other.labels[box][inside])
            common[0] = 0
            common[other.roles[: len(common)] == ISLAND] = 0
            best = int(np.argmax(common))
            area, best_area = int(inside.sum()), int(other.areas[best])
            if common[best] and common[best] / (area + best_area - common[best]) >= min_iou:
                found.add((best, int(label)) if not flip else (int(label), best))
    return np.array(sorted(found), np.int64).reshape(-1, 2)


def _groups(pairs: np.ndarray, na: int, nb: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Connected groups of the partner graph: group ids per normal and per defect label
    (-1: no partner) and the number of groups."""
    parent = np.arange(na + nb)

    def find(x: int) -> int:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for a, b in pairs.tolist():
        ra, rb = find(a), find(na + b)
        if ra != rb:
            parent[ra] = rb
    group_a = np.full(na, -1, np.int64)
    group_b = np.full(nb, -1, np.int64)
    ids: dict[int, int] = {}
    for a, b in pairs.tolist():
        g = ids.setdefault(find(a), len(ids))
        group_a[a] = g
        group_b[b] = g
    return group_a, group_b, len(ids)


# --------------------------------------------------------------------------- distance
@dataclass(frozen=True)
class ContourShift:
    """The largest distance between corresponding contours, and where it is: ``column``
    (of the cut image; -1 when nothing was compared), the contour's row in the normal and
    in the defect image, and ``side``: ``"upper"`` or ``"lower"`` contour."""

    distance_px: float = 0.0
    column: int = -1
    normal_row: float = float("nan")
    defect_row: float = float("nan")
    side: str = ""

    def in_image(self, first_column: int) -> ContourShift:
        """The same shift with its column counted in the uncut image."""
        return self if self.column < 0 else replace(self, column=self.column + first_column)


def _extremes(runs: Runs, group: np.ndarray, groups: int, width: int, upper: bool) -> np.ndarray:
    """Per (group, column): the top-most (upper) or bottom-most row of the group."""
    out = np.full(groups * width, np.inf if upper else -np.inf)
    g = group[runs.labels]
    keep = g >= 0
    index = (g[keep] * width + runs.cols[keep]).astype(
        np.intp
    )  # flat indices: ufunc.at's fast path
    (np.minimum if upper else np.maximum).at(out, index, runs.rows[keep].astype(np.float64))
    return out.reshape(groups, width)


def contour_shift(normal: StripeMap, defect: StripeMap, pairs: np.ndarray) -> ContourShift:
    """Largest vertical distance between corresponding contours (step 5 of the metric)."""
    if len(pairs) == 0:
        return ContourShift()
    group_a, group_b, groups = _groups(pairs, normal.count + 1, defect.count + 1)
    width = normal.labels.shape[1]
    found = []
    for upper, side in ((True, "upper"), (False, "lower")):
        runs_a, runs_b = (normal.top, defect.top) if upper else (normal.bottom, defect.bottom)
        a = _extremes(runs_a, group_a, groups, width, upper)
        b = _extremes(runs_b, group_b, groups, width, upper)
        both = np.isfinite(a) & np.isfinite(b)
        if both.any():
            gap = np.full(a.shape, -1.0)
            np.subtract(a, b, out=gap, where=both)
            np.abs(gap, out=gap, where=both)
            g, column = divmod(int(np.argmax(gap)), width)
            found.append(
                ContourShift(
                    float(gap[g, column]), column, float(a[g, column]), float(b[g, column]), side
                )
            )
    return max(found, key=lambda s: s.distance_px, default=ContourShift())


@dataclass(frozen=True)
class PhaseResult:
    """The comparison at one phase: the ``shift`` between corresponding contours, the
    ``islands`` the defect adds (the defect image's islands beyond the defect-free one's),
    stripes of either image left ``unpaired``, and the number of partner ``pairs``."""

    phase_mm: float
    shift: ContourShift
    islands: int
    unpaired: int
    pairs: int

    @property
    def distance_px(self) -> float:
        return self.shift.distance_px


def compare(
    normal: StripeMap, defect_binary: np.ndarray, edge: np.ndarray | None, phase_mm: float = 0.0
) -> PhaseResult:
    """Steps 3–5 at one phase: the defect image (cut, bool) against the normal stripes."""
    defect = find_stripes(defect_binary, edge)
    pairs = pair_stripes(normal, defect)
    paired_a = np.unique(pairs[:, 0]) if len(pairs) else np.empty(0, np.int64)
    paired_b = np.unique(pairs[:, 1]) if len(pairs) else np.empty(0, np.int64)
    bearing = int(
        np.count_nonzero(normal.roles[1:] != ISLAND) + np.count_nonzero(defect.roles[1:] != ISLAND)
    )
    unpaired = bearing - len(paired_a) - len(paired_b)
    islands = max(0, defect.islands - normal.islands)  # a curved base may close stripes by itself
    return PhaseResult(
        phase_mm, contour_shift(normal, defect, pairs), islands, unpaired, len(pairs)
    )


# --------------------------------------------------------------------------- registration
def contour_image(binary: np.ndarray) -> np.ndarray:
    """The stripe contours of a binary image: white pixels with a black 4-neighbour
    (uint8 0/255)."""
    white = np.asarray(binary, np.uint8)
    inner = cv2.erode(white, _CROSS, borderType=cv2.BORDER_REPLICATE)
    return ((white > 0) & (inner == 0)).astype(np.uint8) * 255


def register(
    normal_binary: np.ndarray, defect_binary: np.ndarray, max_offset_px: int = 8
) -> tuple[int, int]:
    """Whole-pixel offset ``(dx, dy)`` that moves the defect image onto the normal one
    (step 4 of the metric): the shift within ``±max_offset_px`` that best correlates their
    contour images (normalised cross-correlation); among equally good shifts the
    smallest wins, so a pattern that is blind to a direction (horizontal stripes are
    blind to horizontal shifts) is not moved along it. Zero for rendered pairs.

    Phase correlation is not used: on a periodic stripe pattern its peak is ambiguous
    up to whole periods.
    """
    a = contour_image(normal_binary).astype(np.float32)
    b = contour_image(defect_binary).astype(np.float32)
    m = max_offset_px
    h, w = a.shape
    if m == 0 or not a.any() or not b.any() or h <= 2 * m + 1 or w <= 2 * m + 1:
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


# --------------------------------------------------------------------------- pictures
def overlay_rgb(normal: StripeMap, defect: StripeMap) -> np.ndarray:
    """Fig. 9 of the paper on the cut images (uint8 RGB): contours of the normal image in
    blue, of the defect image in red, where they coincide magenta; contours of the defect
    image's islands, which the metric does not measure, in orange."""
    a = contour_image(normal.labels > 0) > 0
    b = contour_image(defect.labels > 0) > 0
    island = b & (defect.roles[defect.labels] == ISLAND) & (defect.labels > 0)
    rgb = np.zeros(a.shape + (3,), np.uint8)
    rgb[a, 2] = 255
    rgb[b & ~island, 0] = 255
    rgb[island] = (255, 150, 0)
    return rgb
