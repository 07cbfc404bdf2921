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
#: The role of a label that names no stripe of this image (a defect image compared in the
#: dent's region: the defect-free stripes the dent touched are relabelled there).
UNUSED = 3
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

    @property
    def nbytes(self) -> int:
        """Bytes its arrays take, with the per-label tables made on first use
        (:attr:`areas`, :attr:`extents`: 40 bytes a label)."""
        runs = sum(a.nbytes for r in (self.top, self.bottom) for a in (r.rows, r.cols, r.labels))
        return self.labels.nbytes + self.roles.nbytes + runs + 40 * len(self.roles)

    @property
    def bearing(self) -> np.ndarray:
        """Per label: True for a contour-bearing stripe (``CUT`` or ``BORDER``)."""
        return (self.roles == CUT) | (self.roles == BORDER)

    @cached_property
    def extents(self) -> np.ndarray:
        """Per label: its first row, last row + 1, first column, last column + 1 (int64,
        shape (count + 1, 4); label 0 and absent labels hold an empty box)."""
        size = len(self.roles)
        box = np.empty((size, 4), np.int64)
        box[:, 0] = box[:, 2] = np.iinfo(np.int64).max
        box[:, 1] = box[:, 3] = np.iinfo(np.int64).min
        np.minimum.at(box[:, 0], self.top.labels, self.top.rows)
        np.maximum.at(box[:, 1], self.bottom.labels, self.bottom.rows + 1)
        np.minimum.at(box[:, 2], self.top.labels, self.top.cols)
        np.maximum.at(box[:, 3], self.top.labels, self.top.cols + 1)
        return box

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
    if edge is None:
        edge = np.zeros(labels.shape, bool)
        edge[0] = edge[-1] = True
    roles = _roles(labels, count, edge, (0, -1))
    top, bottom = _run_ends(labels)
    return StripeMap(labels=labels, roles=roles, top=top, bottom=bottom)


def _roles(
    labels: np.ndarray, count: int, edge: np.ndarray, cut_columns: tuple[int, ...]
) -> np.ndarray:
    """Each label's role: ``CUT`` where it touches one of ``cut_columns``, else ``BORDER``
    where it has a pixel in ``edge``, else ``ISLAND``."""
    roles = np.full(count, ISLAND, np.uint8)
    on_edge = np.zeros(count, bool)
    on_edge[labels[edge]] = True
    roles[on_edge] = BORDER
    for column in cut_columns:
        roles[labels[:, column]] = CUT
    roles[0] = ISLAND
    return roles


def _run_ends(labels: np.ndarray, white: np.ndarray | None = None) -> tuple[Runs, Runs]:
    """The first (top) and last (bottom) pixel of every run of a label in a column
    (``white``: ``labels > 0``, when the caller has it). Vertically adjacent white pixels
    share their label, so a run starts below a black pixel and ends above one."""
    if white is None:
        white = labels > 0
    starts = white.copy()
    starts[1:] &= ~white[:-1]
    ends = white.copy()
    ends[:-1] &= ~white[1:]
    return _runs(labels, starts), _runs(labels, ends)


def _runs(labels: np.ndarray, mask: np.ndarray) -> Runs:
    flat = np.flatnonzero(mask)  # about 3x faster than a 2-D nonzero
    rows, cols = np.divmod(flat, labels.shape[1])
    return Runs(rows=rows, cols=cols, labels=labels.ravel()[flat])


# --------------------------------------------------------------------------- pairing
def pair_stripes(
    normal: StripeMap,
    defect: StripeMap,
    min_iou: float = 0.5,
    cut_columns: tuple[int, ...] = (0, -1),
) -> np.ndarray:
    """Partners ``(label_normal, label_defect)`` by identity (an int64 array of shape (K, 2)).

    1. ``CUT`` stripes that share a pixel at a cut column (``cut_columns`` of the label
       images: both ends of the cut image, unless the images are a part of it).
    2. A ``BORDER`` stripe left without a partner: the contour-bearing stripe of the other
       image that overlaps it most, if their intersection over union is >= ``min_iou``.
    Islands are never paired.
    """
    nb = len(defect.roles)
    keys = [np.empty(0, np.int64)]
    for column in cut_columns:
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
            common[~other.bearing[: len(common)]] = 0
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
    group_a, group_b, groups = _groups(pairs, len(normal.roles), len(defect.roles))
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
    bearing = int(np.count_nonzero(normal.bearing) + np.count_nonzero(defect.bearing))
    unpaired = bearing - len(paired_a) - len(paired_b)
    islands = max(0, defect.islands - normal.islands)  # a curved base may close stripes by itself
    return PhaseResult(
        phase_mm, contour_shift(normal, defect, pairs), islands, unpaired, len(pairs)
    )


# --------------------------------------------------------------------------- in a region
@dataclass(frozen=True)
class Patch:
    """Where a defect image differs from the defect-free one: its pixels ``binary`` (bool)
    over the box ``rows`` x ``cols`` of the cut image. Outside the box the images are equal."""

    rows: slice
    cols: slice
    binary: np.ndarray


def compare_patched(
    normal: StripeMap, patch: Patch, edge: np.ndarray, phase_mm: float = 0.0
) -> PhaseResult | None:
    """:func:`compare` of the defect image that is ``normal``'s image with ``patch`` written
    over it, worked out around the patch only. ``edge``: the border pixels (full cut size).

    A stripe of the defect-free image that neither enters the patch nor touches its
    one-pixel ring is *untouched*: the defect image has the very same component (same
    pixels, same role), it partners only itself, and its contours are 0 px apart. Every
    other component of the defect image is made of pixels of the patch, of its ring and of
    the touched stripes, so labelling the box that holds them (the crop) finds them exactly;
    pairing, islands and distances there are those of the whole image, the untouched
    stripes adding their identity pairs. Returns None when the largest distance is 0 (the
    whole image then decides which column a 0 is reported at).
    """
    height, width = normal.labels.shape
    ring = (
        slice(max(patch.rows.start - 1, 0), min(patch.rows.stop + 1, height)),
        slice(max(patch.cols.start - 1, 0), min(patch.cols.stop + 1, width)),
    )
    touched = np.bincount(normal.labels[ring].ravel(), minlength=len(normal.roles)) > 0
    touched[0] = False
    crop = _crop(normal.extents[touched], ring)
    origin = (crop[0].start, crop[1].start)
    labels = normal.labels[crop]
    white = labels > 0
    around = normal.labels[ring] > 0
    around[_within((patch.rows, patch.cols), (ring[0].start, ring[1].start))] = patch.binary
    white[_within(ring, origin)] = around
    count, fresh = cv2.connectedComponents(white.view(np.uint8), connectivity=8, ltype=cv2.CV_32S)
    cuts = tuple(c for c, at in ((0, crop[1].start == 0), (-1, crop[1].stop == width)) if at)
    new_roles = _roles(fresh, count, edge[crop], cuts)
    top, bottom = _run_ends(fresh, white)
    # an untouched stripe (or a piece of it the crop cut off) is labelled too: not the
    # defect image's to compare, it names its own pixels in both images
    under = labels[top.rows, top.cols]
    new_roles[top.labels[(under > 0) & ~touched[under]]] = UNUSED
    defect = StripeMap(labels=fresh, roles=new_roles, top=top, bottom=bottom)
    normal_roles = np.where(touched, normal.roles, UNUSED).astype(np.uint8)
    normal_roles[0] = ISLAND
    mine = StripeMap(
        labels=labels,
        roles=normal_roles,
        top=_moved(normal.top, touched, origin),
        bottom=_moved(normal.bottom, touched, origin),
    )
    pairs = pair_stripes(mine, defect, cut_columns=cuts)
    pairs = pairs[touched[pairs[:, 0]]]  # an untouched stripe partners itself: counted below
    shift = contour_shift(mine, defect, pairs)
    if shift.distance_px <= 0.0:
        return None
    shift = replace(
        shift,
        column=int(shift.column + origin[1]),
        normal_row=float(shift.normal_row + origin[0]),
        defect_row=float(shift.defect_row + origin[0]),
    )
    paired = len(np.unique(pairs[:, 0])) + len(np.unique(pairs[:, 1]))
    unpaired = int(np.count_nonzero(mine.bearing) + np.count_nonzero(defect.bearing)) - paired
    islands = int(np.count_nonzero(new_roles[1:] == ISLAND))
    islands -= int(np.count_nonzero(normal.roles[touched] == ISLAND))
    untouched_pairs = int(np.count_nonzero(normal.bearing & ~touched))
    return PhaseResult(phase_mm, shift, max(0, islands), unpaired, untouched_pairs + len(pairs))


def _crop(extents: np.ndarray, ring: tuple[slice, slice]) -> tuple[slice, slice]:
    """The box holding ``ring`` and every touched stripe (their ``extents`` rows)."""
    if not len(extents):
        return ring
    return (
        slice(
            min(ring[0].start, int(extents[:, 0].min())),
            max(ring[0].stop, int(extents[:, 1].max())),
        ),
        slice(
            min(ring[1].start, int(extents[:, 2].min())),
            max(ring[1].stop, int(extents[:, 3].max())),
        ),
    )


def _within(box: tuple[slice, slice], origin: tuple[int, int]) -> tuple[slice, slice]:
    """``box`` counted from ``origin``."""
    return (
        slice(box[0].start - origin[0], box[0].stop - origin[0]),
        slice(box[1].start - origin[1], box[1].stop - origin[1]),
    )


def _moved(runs: Runs, keep: np.ndarray, origin: tuple[int, int]) -> Runs:
    """The runs of the labels in ``keep``, counted from ``origin``."""
    mask = keep[runs.labels]
    return Runs(
        rows=runs.rows[mask] - origin[0], cols=runs.cols[mask] - origin[1], labels=runs.labels[mask]
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
