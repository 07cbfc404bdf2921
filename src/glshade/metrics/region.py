"""The dent's region of influence: the box of the cut image outside which the images with
and without the dent are the same, at every phase of the sweep.

A Gaussian dent moves the emitter map ``v`` inside a bounded region (its extent in the
image, widened by the largest deflection: the closed forms of
:mod:`glshade.metrics.physics` and :func:`glshade.metrics.status.dent_window`), but its
tail changes ``v`` by float32 rounding far beyond it. The region is therefore taken from
the maps themselves, never from the closed form alone:

- every pixel where ``|v1 - v0|`` exceeds :data:`TOLERANCE_SHARE` of the stripe period,
  or where one map sees the emitter and the other does not, is in it;
- a pixel that moves by less can change its binary value only if ``v0`` lies within
  that tolerance of a binarisation level of some phase. Those pixels are few (about 0.2 %
  of the image) and found once per geometry (:class:`RegionBasis`); for each dent they are
  binarised at every phase with both maps, exactly as the metric does, and every one that
  flips is in the region.

So the region is never smaller than the rows and columns where the two binary images
differ, at any phase: the contour analysis inside it (:func:`glshade.metrics.contours.
compare_patched`) gives the full-frame answer by construction.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from glshade.metrics.continuous import ColumnOrder, Focus, column_order

#: A pixel whose emitter coordinate moves by more than this share of the stripe period
#: is in the region outright (2 mm stripes: 0.1 µm).
TOLERANCE_SHARE = 5e-5

#: Pixels whose move, divided by the defect-free map's slope beside them, is below this
#: (px) are not searched for the deflection: their displacement is at most this, and the
#: numbers are taken from the region only when they exceed it.
SEARCHED_PX = 0.01

Box = tuple[slice, slice]


@dataclass(frozen=True)
class Influence:
    """The region of one dent in the cut image: ``box`` (rows, columns; None when the two
    maps are equal everywhere) and the tolerance used (mm): outside the box ``|v1 - v0|``
    is at most ``tolerance_mm`` and no binary pixel differs at any phase. ``searched``: the
    pixels (flat indices) whose displacement may exceed :data:`SEARCHED_PX` (their move
    times the defect-free map's rows per mm beside them, or one map sees nothing there)."""

    box: Box | None
    tolerance_mm: float
    searched: np.ndarray


class RegionBasis:
    """What the region needs of the defect-free map, once per geometry: ``v0`` cut to the
    kept columns, its no-hit pixels, and the pixels near a binarisation level.

    ``binary(v, phase)`` is the metric's own binarisation of emitter coordinates (a 1-D
    array), so the flips are decided by the same arithmetic as the images.
    """

    def __init__(
        self,
        v0_cut: np.ndarray,
        phases: np.ndarray,
        period_mm: float,
        half_width_mm: float,
        binary: Callable[[np.ndarray, float], np.ndarray] | None,
    ) -> None:
        self.v0 = v0_cut
        self.phases = tuple(float(p) for p in phases)
        self.tolerance_mm = TOLERANCE_SHARE * period_mm
        self.binary = binary
        self.unseen = np.isnan(v0_cut)
        self.order: ColumnOrder = column_order(v0_cut)
        #: rows per mm beside each pixel, finite (a flat segment: a huge number)
        self.rows_per_mm = np.minimum(self.order.rows_per_mm, np.float32(1e30))
        with np.errstate(invalid="ignore"):
            steps = np.abs(np.diff(np.asarray(v0_cut, np.float64), axis=0))
            self.fold_pairs = np.flatnonzero(steps <= 2.0 * self.tolerance_mm * (1.0 + 1e-6))
        if binary is None:  # the images are rendered: the contours find their own region
            self.near = np.empty(0, np.int64)
        else:
            near = near_levels(v0_cut, self.phases, period_mm, half_width_mm, self.tolerance_mm)
            self.near = np.flatnonzero(near)
        self.near_v0 = v0_cut.ravel()[self.near]

    def influence(self, v1_cut: np.ndarray) -> Influence:
        """The region of the dent whose (cut) emitter map is ``v1_cut``."""
        moved = np.abs(v1_cut - self.v0)
        beyond = ~(moved <= self.tolerance_mm)  # NaN (one map sees nothing) counts
        beyond &= ~(self.unseen & np.isnan(v1_cut))  # neither sees: unchanged
        rows = beyond.any(axis=1)
        cols = beyond.any(axis=0)
        flips = self._flips(v1_cut)
        if len(flips):
            r, c = np.divmod(flips, self.v0.shape[1])
            rows[r] = True
            cols[c] = True
        lost = beyond & np.isnan(moved)
        np.nan_to_num(moved, copy=False)
        moved *= self.rows_per_mm  # at most the pixel's displacement, in px, where it is small
        searched = np.flatnonzero(lost | (moved > SEARCHED_PX))
        return Influence(_box(rows, cols), self.tolerance_mm, searched)

    def focus(self, influence: Influence) -> Focus | None:
        """Where the continuous numbers of a dent are computed (None: everywhere)."""
        if influence.box is None:
            return None
        pixels = np.concatenate([influence.searched, self.order.far])
        return Focus(influence.box, pixels, self.fold_pairs, SEARCHED_PX)

    def _flips(self, v1_cut: np.ndarray) -> np.ndarray:
        """Near-level pixels (flat indices) whose binary value differs at some phase. Only
        the pixels whose coordinate changed can flip (the binarisation is a function of
        the coordinate alone); both maps are binarised there phase by phase, so nothing
        is kept per phase."""
        if self.binary is None or not len(self.near):
            return self.near
        v1 = v1_cut.ravel()[self.near]
        changed = np.flatnonzero(~(v1 == self.near_v0))  # NaN != NaN: kept, as before
        v1, v0 = v1[changed], self.near_v0[changed]
        differs = np.zeros(len(changed), bool)
        for phase in self.phases:
            differs |= self.binary(v1, phase) != self.binary(v0, phase)
        return self.near[changed[differs]]


def _box(rows: np.ndarray, cols: np.ndarray) -> Box | None:
    r, c = np.flatnonzero(rows), np.flatnonzero(cols)
    if not len(r):
        return None
    return slice(int(r[0]), int(r[-1]) + 1), slice(int(c[0]), int(c[-1]) + 1)


def near_levels(
    v0: np.ndarray,
    phases: tuple[float, ...],
    period_mm: float,
    half_width_mm: float,
    tolerance_mm: float,
) -> np.ndarray:
    """Pixels whose ``v0`` lies within ``tolerance_mm`` (and the rounding of float32
    coordinates) of a stripe edge ``phase ± half_width + k period`` of some phase (bool).

    Phases a whole period apart in equal steps (the sweep's usual case) put the edges on two
    combs of that step: the distance to each is one remainder; other phases are looked up
    among the sorted edges."""
    finite = v0[np.isfinite(v0)]
    scale = float(np.abs(finite).max()) if finite.size else 0.0
    margin = tolerance_mm + 8.0 * float(np.finfo(np.float32).eps) * (scale + period_mm)
    v = np.asarray(v0, np.float64)
    step = phases[1] - phases[0] if len(phases) > 1 else period_mm
    combs = np.allclose(phases, phases[0] + step * np.arange(len(phases)), rtol=0, atol=1e-12)
    if combs and abs(step * len(phases) - period_mm) <= 1e-9 * period_mm:
        near = np.zeros(v.shape, bool)
        with np.errstate(invalid="ignore"):
            for edge in (phases[0] + half_width_mm, phases[0] - half_width_mm):
                rest = np.mod(v - edge, step)
                near |= np.minimum(rest, step - rest) <= margin
        return near
    levels = np.sort(
        np.mod(
            np.concatenate([np.add(phases, half_width_mm), np.subtract(phases, half_width_mm)]),
            period_mm,
        )
    )
    ring = np.concatenate([levels - period_mm, levels, levels + period_mm])
    u = np.mod(v, period_mm)
    at = np.clip(np.searchsorted(ring, u), 1, len(ring) - 1)
    with np.errstate(invalid="ignore"):
        gap = np.minimum(np.abs(u - ring[at - 1]), np.abs(ring[at] - u))
        return gap <= margin
