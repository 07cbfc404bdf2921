"""The paper's contour comparison (SPEC §6) on synthetic binary images whose answer is
known by construction, and the continuous limit on an analytic folded map."""

from __future__ import annotations

import math

import numpy as np
import pytest

from glshade.metrics import contours as ct
from glshade.metrics import visibility as V
from glshade.metrics.continuous import StripeLevels, deflection, visibility_limit

H, W = 150, 200  # a cut image: columns 0 and W-1 are the cut columns
BASE_ROWS = (10, 40, 70, 100, 130)  # stripes 6 px thick, 30 px apart
THICK = 6


def stripes(shift=lambda stripe, col: 0):
    """A binary image of horizontal stripes; stripe ``i`` in column ``c`` covers rows
    ``BASE_ROWS[i] + shift(i, c)`` onwards for ``THICK`` rows."""
    image = np.zeros((H, W), bool)
    for i, row in enumerate(BASE_ROWS):
        for c in range(W):
            top = row + int(shift(i, c))
            image[max(0, top) : max(0, top + THICK), c] = True
    return image


def bump(col: int, centre: float = 100.0, width: float = 15.0) -> float:
    return math.exp(-0.5 * ((col - centre) / width) ** 2)


def measure(normal: np.ndarray, defect: np.ndarray, edge=None) -> ct.PhaseResult:
    return ct.compare(ct.find_stripes(normal, edge), defect, edge)


@pytest.mark.parametrize("k", [1, 3, 7])
def test_a_contour_shifted_by_k_pixels(k):
    """Stripe 2 moves down by k rows over columns 80-119 (ramps of one row per column on
    either side keep it one stripe): the distance is exactly k, in those columns."""
    normal = stripes()
    defect = stripes(lambda i, c: min(k, max(0, c - 80 + k), max(0, 119 + k - c)) if i == 2 else 0)
    result = measure(normal, defect)
    assert result.distance_px == k
    assert 80 <= result.shift.column < 120
    assert result.shift.defect_row - result.shift.normal_row in (k, -k)
    assert (result.islands, result.unpaired, result.pairs) == (0, 0, len(BASE_ROWS))
    assert measure(normal, normal).distance_px == 0


def test_identity_not_nearness():
    """Stripe 2 sinks 20 rows (2/3 of the period): it then lies 4 rows above stripe 3, but
    it is compared with itself: 20, not 4."""
    normal = stripes()
    defect = stripes(lambda i, c: round(20 * bump(c, width=25.0)) if i == 2 else 0)
    result = measure(normal, defect)
    assert result.distance_px == 20
    assert result.shift.normal_row in (70, 75) and result.shift.defect_row in (90, 95)


def test_a_fold_island_is_counted_never_measured():
    """A closed piece of stripe between stripes 1 and 2 (touching neither a cut column
    nor the border): one island, and no distance at all."""
    normal = stripes()
    defect = normal.copy()
    defect[52:56, 90:110] = True
    result = measure(normal, defect)
    assert result.islands == 1
    assert result.distance_px == 0
    assert result.unpaired == 0


def test_outermost_crossing_not_every_edge():
    """Inside a stripe, a dark hole (the fold's reversed piece) adds inner edges; the
    contours are the outermost crossings, which do not move: distance 0. (Comparing every
    edge with the nearest one of its partner would report the hole, 3 px.)"""
    normal = stripes()
    defect = normal.copy()
    defect[43, 90:110] = False  # stripe 2 (rows 40-45) split into 40-42 and 44-45 there
    result = measure(normal, defect)
    assert result.distance_px == 0 and result.islands == 0


def test_a_stripe_turned_over_is_measured_at_its_outermost_crossing():
    """A tongue of stripe 2 pokes 7 rows above it, joined to it: in those columns the
    stripe crosses the column twice, and its upper contour is the outermost crossing,
    the tongue's top (33 instead of 40)."""
    normal = stripes()
    defect = normal.copy()
    defect[33:36, 95:106] = True  # the tongue
    defect[36:40, 95] = True  # its join to the stripe
    result = measure(normal, defect)
    assert result.distance_px == 7
    assert result.shift.side == "upper" and (result.shift.normal_row, result.shift.defect_row) == (
        40.0,
        33.0,
    )
    assert result.islands == 0


def test_an_arc_through_the_border_is_a_contour():
    """An arc that enters and leaves through the top row (no cut column) is a contour:
    paired with the other image's arc by overlap, its shift is measured. A piece that
    touches nothing is an island; a piece that touches the edge of the region that sees
    the emitter is a contour too."""
    normal = np.zeros((H, W), bool)
    arc_rows = {c: 10 + round(40 * math.sin(math.pi * (c - 40) / 120)) for c in range(40, 161)}
    for c, row in arc_rows.items():
        normal[0 : row + 1, c] = True  # a thick arc hanging from the top row
    defect = normal.copy()
    for c, row in arc_rows.items():
        defect[row + 1 : row + 1 + round(3 * bump(c)), c] = True  # its lower contour sinks 3 px
    defect[120:124, 90:100] = True  # an island
    stripes_n = ct.find_stripes(normal)
    assert stripes_n.roles[1] == ct.BORDER
    result = ct.compare(stripes_n, defect, None)
    assert result.distance_px == 3 and result.shift.side == "lower"
    assert result.islands == 1 and result.pairs == 1 and result.unpaired == 0
    # the same island touching a region that does not see the emitter is a contour
    valid = np.ones((H, W), bool)
    valid[124:, :] = False
    edge = ct.border_pixels(valid)
    roles = ct.find_stripes(defect & valid, edge).roles
    assert sorted(roles[1:].tolist()) == [ct.BORDER, ct.BORDER]


def test_split_and_merged_stripes_are_compared_as_one():
    """Pixelation breaks stripe 2 of the defect image in two (a gap at columns 95-105):
    both pieces are its partners, nothing is unpaired, the distance is 0 where both
    images have it. A one-pixel bridge joins stripes 2 and 3: the merged stripe is compared
    as one group (upper with stripe 2's, lower with stripe 3's) and no period-sized
    distance appears."""
    normal = stripes()
    split = normal.copy()
    split[40:46, 95:106] = False
    result = measure(normal, split)
    assert (result.distance_px, result.unpaired, result.islands) == (0, 0, 0)
    assert result.pairs == len(BASE_ROWS) + 1
    merged = normal.copy()
    merged[46:70, 100] = True
    result = measure(normal, merged)
    assert (result.distance_px, result.unpaired, result.islands) == (0, 0, 0)


def test_registration_finds_a_whole_pixel_move():
    normal = stripes(lambda i, c: round(3 * math.sin(c / 17.0)))  # not blind to horizontal moves
    moved = np.zeros_like(normal)
    moved[2:, :-3] = normal[:-2, 3:]  # 2 rows down, 3 columns left
    assert ct.register(normal, moved, 8) == (3, -2)
    assert ct.register(normal, normal, 8) == (0, 0)


# --------------------------------------------------------------------------- the limit
def folded_maps(deflection_px=18.0, b_px=2.5, width_px=30.0, mm_per_row=0.0863, size=(200, 400)):
    """The emitter maps of a dent's fold along the column (docs/physics.md §3):
    ``v1 = v0 - s Δ(ρ) g(col)``, ``Δ(ρ) = D t e^((1-t²)/2)``, ``t = ρ / b``."""
    rows, cols = np.mgrid[0 : size[0], 0 : size[1]].astype(np.float64)
    t = (rows - size[0] / 2) / b_px
    g = np.exp(-0.5 * ((cols - size[1] / 2) / width_px) ** 2)
    v0 = rows * mm_per_row
    return v0, v0 - mm_per_row * deflection_px * t * np.exp(0.5 * (1 - t * t)) * g


def test_the_limit_on_an_analytic_fold_is_the_cap_of_physics_md():
    """The rays move 18 px, but the contours that reach the cut columns move only by
    b sqrt(2 ln F), F = D e^(1/2) / b: 5.56 px. Without the fold (a shallower profile)
    the limit is the deflection."""
    d, b = 18.0, 2.5
    v0, v1 = folded_maps(d, b)
    columns = slice(100, 300)
    valid = np.ones(v0.shape, bool)
    levels = StripeLevels(period_mm=2.0, half_width_mm=0.5014)
    moved = deflection(v0, v1, columns)
    assert moved.folded
    t = (np.arange(200) - 100) / b  # v1 = s (r - Δ(r)): exactly Δ at each sampled row
    assert moved.deflection_px == pytest.approx(np.max(d * t * np.exp(0.5 * (1 - t * t))), rel=1e-6)
    limit = visibility_limit(v0, v1, valid, columns, levels, moved)
    cap = b * math.sqrt(2 * math.log(d * math.sqrt(math.e) / b))
    assert limit.visibility_px == pytest.approx(cap, rel=0.03)
    v0, v1 = folded_maps(1.2, b)  # F < 1: no fold, the limit is the deflection
    moved = deflection(v0, v1, columns)
    assert not moved.folded
    assert visibility_limit(v0, v1, valid, columns, levels, moved).visibility_px == pytest.approx(
        moved.deflection_px, rel=1e-6
    )


# ------------------------------------------------------------------ more cases by construction
# Small images (60×40 unless stated): each stripe spans rows [top, bottom) in every column.
def bands(*rows, height: int = 60, width: int = 40) -> np.ndarray:
    out = np.zeros((height, width), bool)
    for top, bottom in rows:
        out[top:bottom] = True
    return out


def roles_of(binary: np.ndarray, edge: np.ndarray | None = None) -> list[int]:
    """The roles of the stripes, in label order (row-major scan)."""
    return ct.find_stripes(binary, edge).roles[1:].tolist()


def nearest_edge_distance(normal: np.ndarray, defect: np.ndarray) -> int:
    """For contrast only: the largest distance from any top (bottom) edge of one image to
    the nearest top (bottom) edge of the other in the same column, both ways: the
    nearest-edge rule SPEC §6 does not use."""
    worst = 0
    for a, b in ((normal, defect), (defect, normal)):
        for starts in (True, False):
            ea, eb = _run_ends(a, starts), _run_ends(b, starts)
            for j in range(a.shape[1]):
                ra, rb = np.nonzero(ea[:, j])[0], np.nonzero(eb[:, j])[0]
                if len(ra) and len(rb):
                    worst = max(worst, int(np.abs(ra[:, None] - rb[None, :]).min(axis=1).max()))
    return worst


def _run_ends(binary: np.ndarray, starts: bool) -> np.ndarray:
    out = binary.copy()
    if starts:
        out[1:] &= ~binary[:-1]
    else:
        out[:-1] &= ~binary[1:]
    return out


@pytest.mark.parametrize("k", [1, 3, 7])
@pytest.mark.parametrize("side", ["upper", "lower"])
def test_one_contour_moved_by_k_is_measured_on_its_own_side(k, side):
    """Only the upper stripe's top (or only the lower stripe's bottom) moves out by k in
    columns 15-24: distance k, on that side, at those rows; the same through the whole
    phase sweep of image_visibility (every column kept, images that ignore the phase)."""
    normal = bands((10, 20), (35, 45))
    defect = normal.copy()
    if side == "upper":
        defect[10 - k : 10, 15:25] = True
    else:
        defect[45 : 45 + k, 15:25] = True
    result = measure(normal, defect)
    assert result.shift.distance_px == k and result.shift.side == side
    assert 15 <= result.shift.column <= 24
    assert (result.shift.normal_row, result.shift.defect_row) == (
        (10.0, 10.0 - k) if side == "upper" else (44.0, 44.0 + k)
    )
    assert (result.pairs, result.unpaired, result.islands) == (2, 0, 0)
    paper = V.image_visibility(
        lambda p: normal * 1.0, lambda p: defect * 1.0, 2.0, V.MetricSettings(keep_fraction=1.0)
    )
    assert paper.visibility_px == k and paper.offset_px == (0, 0) and paper.shift.side == side
    assert 15 <= paper.shift.column <= 24
    assert len(paper.per_phase) == 8 and all(r.distance_px == k for r in paper.per_phase)


def test_a_piece_cut_out_of_a_stripe_is_an_island_not_a_shift():
    """A fold moves the middle of the upper stripe 12-14 rows down and cuts it loose: the
    loose piece is an island (counted, not measured), the two ends of the stripe still
    pair with the normal stripe and do not move: distance 0, not 12."""
    normal = bands((10, 20), (35, 45))
    defect = normal.copy()
    defect[10:20, 15:25] = False
    defect[24:32, 17:23] = True
    assert roles_of(defect) == [ct.CUT, ct.CUT, ct.ISLAND, ct.CUT]
    result = measure(normal, defect)
    assert result.islands == 1 and result.shift.distance_px == 0.0
    assert (result.pairs, result.unpaired) == (3, 0)


def test_the_outermost_rule_and_a_nearest_edge_rule_disagree():
    """A black gap (rows 13-15, columns 15-24) splits the stripe's run in two: its
    outermost crossings (top 10, bottom 19) have not moved, distance 0; a nearest-edge
    rule would measure the gap's edges, 7 px."""
    normal = bands((10, 20), (35, 45))
    defect = normal.copy()
    defect[13:16, 15:25] = False
    assert nearest_edge_distance(normal, defect) == 7
    result = measure(normal, defect)
    assert result.shift.distance_px == 0.0 and (result.islands, result.unpaired) == (0, 0)


def arc_pair():
    """An arc hanging from the top row (no cut column) above a cut-to-cut stripe; in the
    defect image the arc's bottom drops by 3 in columns 16-23."""
    normal = bands((25, 32), height=40)
    normal[0:8, 12:28] = True
    defect = normal.copy()
    defect[8:11, 16:24] = True
    return normal, defect


def test_an_arc_is_paired_by_overlap_and_its_shift_measured():
    normal, defect = arc_pair()
    assert roles_of(normal) == roles_of(defect) == [ct.BORDER, ct.CUT]
    assert ct.pair_stripes(ct.find_stripes(normal), ct.find_stripes(defect)).tolist() == [
        [1, 1],
        [2, 2],
    ]
    result = measure(normal, defect)
    assert (
        result.shift.distance_px == 3.0
        and result.shift.side == "lower"
        and 16 <= result.shift.column <= 23
    )
    assert (result.shift.normal_row, result.shift.defect_row) == (7.0, 10.0)
    assert (result.pairs, result.unpaired, result.islands) == (2, 0, 0)


def test_an_arc_through_the_border_of_the_valid_region():
    """Rows 0-4 do not see the emitter: the arc touches the region's border (row 5, from
    border_pixels), not the image's top row, and is still a contour; without the region's
    border it touches nothing, is an island, and is not measured."""
    normal, defect = arc_pair()
    valid = np.ones(normal.shape, bool)
    valid[:5] = False
    edge = ct.border_pixels(valid)
    assert edge[5].all() and edge[-1].all() and not edge[:5].any() and not edge[6:-1].any()
    normal, defect = normal & valid, defect & valid
    assert roles_of(normal, edge)[0] == ct.BORDER
    result = measure(normal, defect, edge)
    assert result.shift.distance_px == 3.0 and result.shift.side == "lower" and result.islands == 0
    assert roles_of(normal)[0] == ct.ISLAND
    alone = measure(normal, defect)
    # both images have the arc as an island: the defect adds none, and nothing is measured
    assert (alone.islands, alone.pairs, alone.shift.distance_px) == (0, 1, 0.0)


def test_border_stripes_that_barely_overlap_are_not_partners():
    """Identity by overlap needs essentially the same pixels (IoU >= 0.5): an arc that
    moved by most of its width pairs with nothing; both arcs are reported unpaired and
    nothing is measured."""
    normal, _ = arc_pair()
    defect = normal.copy()
    defect[0:8, 12:28] = False
    defect[0:8, 24:39] = True  # 4 columns in common out of 27
    assert roles_of(defect)[0] == ct.BORDER
    result = measure(normal, defect)
    assert (result.pairs, result.unpaired, result.shift.distance_px) == (1, 2, 0.0)


def test_one_pixel_on_the_border_makes_a_stripe_a_contour():
    binary = np.zeros((30, 30), bool)
    binary[10:15, 10:20] = True
    assert roles_of(binary) == [ct.ISLAND] and ct.find_stripes(binary).islands == 1
    edge = np.zeros_like(binary)
    edge[9, :] = True  # next to it, not on it
    assert roles_of(binary, edge) == [ct.ISLAND]
    edge[10, 12] = True
    assert roles_of(binary, edge) == [ct.BORDER]


def test_a_split_stripe_is_compared_where_both_images_have_it():
    """The upper defect stripe breaks at columns 17-22 and its left piece's top rises by 2
    in columns 12-16: both pieces pair with the normal stripe, the rise is measured, the
    gap is not (it would be 10 rows)."""
    normal = bands((10, 20), (35, 45))
    defect = normal.copy()
    defect[10:20, 17:23] = False
    defect[8:10, 12:17] = True
    assert roles_of(defect) == [ct.CUT, ct.CUT, ct.CUT]
    assert ct.pair_stripes(ct.find_stripes(normal), ct.find_stripes(defect)).tolist() == [
        [1, 1],
        [1, 2],
        [2, 3],
    ]
    result = measure(normal, defect)
    assert (
        result.shift.distance_px == 2.0
        and result.shift.side == "upper"
        and 12 <= result.shift.column <= 16
    )
    assert (result.pairs, result.unpaired, result.islands) == (3, 0, 0)


def test_a_merged_group_still_measures_its_outer_contours():
    """Two defect stripes bridged at columns 18-19 are one component partnering both
    normal stripes: no period-sized (20 px) distance, and a real 1-row rise of the
    group's top in columns 4-6 is measured."""
    normal = bands((10, 18), (30, 38))
    defect = normal.copy()
    defect[18:30, 18:20] = True
    assert ct.find_stripes(defect).count == 1
    assert measure(normal, defect).shift.distance_px == 0.0
    defect[9, 4:7] = True
    result = measure(normal, defect)
    assert (
        result.shift.distance_px == 1.0
        and result.shift.side == "upper"
        and 4 <= result.shift.column <= 6
    )
    assert (result.pairs, result.unpaired) == (2, 0)


@pytest.mark.parametrize("d, b", [(12.0, 3.5), (30.0, 4.5)])
def test_the_limit_converges_on_the_cap_for_other_folds(d, b):
    """Two more folds of the analytic dent (b a half-integer, so t = 1 falls on a whole
    row and the deflection is exactly D): the limit is b sqrt(2 ln F) within 3 % at the
    default sampling and within 1.5 % at a finer one; the window holds the dent's centre."""
    v0, v1 = folded_maps(d, b, size=(81, 120), width_px=10.0)
    columns = V.kept_columns(120, 0.5)
    f = d * math.sqrt(math.e) / b
    assert (
        10.0 * math.sqrt(2 * math.log(f)) < columns.stop - 60
    )  # the fold ends inside the kept columns
    moved = deflection(v0, v1, columns)
    assert moved.folded and moved.deflection_px == pytest.approx(d, rel=1e-9)
    cap = b * math.sqrt(2 * math.log(f))
    levels = StripeLevels(2.0, 0.5)
    coarse = visibility_limit(
        v0, v1, np.isfinite(v0), columns, levels, moved, upsample=2, phase_samples=32
    )
    assert coarse.visibility_px == pytest.approx(cap, rel=0.03)
    r0, r1, c0, c1 = coarse.window
    assert r0 <= 40 < r1 and c0 <= 60 < c1
    fine = visibility_limit(
        v0, v1, np.isfinite(v0), columns, levels, moved, upsample=8, phase_samples=64
    )
    assert fine.visibility_px == pytest.approx(cap, rel=0.015)


def test_only_the_islands_the_defect_adds_are_counted():
    """A closed piece that the defect-free image has too (a curved base can close a
    stripe by itself) is not the defect's: one shared island and one new one count 1."""
    normal = stripes()
    normal[52:56, 20:30] = True  # an island of the base
    defect = normal.copy()
    defect[112:116, 90:110] = True  # an island of the fold
    assert measure(normal, normal).islands == 0
    assert measure(normal, defect).islands == 1
