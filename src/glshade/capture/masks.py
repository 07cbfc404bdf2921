"""Which pixels see the lit screen, from a capture's black and white references
(docs/captures.md): white - black above a threshold found from its histogram, a
neighbourhood vote against specks, and the largest connected region."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from glshade.errors import GlshadeError

#: The histogram's bins, the share of a 9 x 9 neighbourhood a lit pixel needs (4 of 81),
#: and where between the valley and the light peak the threshold lies.
BINS, VOTE_SIDE, VOTE_COUNT, BETWEEN = 100, 9, 4, 0.5


def lit_threshold(black: NDArray[np.generic], white: NDArray[np.generic]) -> float:
    """The white - black threshold: ``BETWEEN`` of the way from the valley of its 100-bin
    histogram to the light peak (the two peaks found as SOFAST finds them: the first
    peak spacing, in steps of 10 bins, that leaves exactly two of density 0.002 or
    more). Where white - black takes two values alone, 0."""
    from scipy.signal import find_peaks

    delta = np.asarray(white, np.float32) - np.asarray(black, np.float32)
    finite = delta[np.isfinite(delta)]
    if np.unique(finite).size <= 2:
        return 0.0
    hist, edges = np.histogram(finite, bins=BINS, density=True)
    peaks = np.array([], np.intp)
    for distance in range(10, BINS, 10):
        peaks = find_peaks(hist, height=0.002, distance=distance)[0]
        if len(peaks) == 2:
            break
    if len(peaks) != 2:
        raise GlshadeError(
            "black and white references: white - black shows no separate dark and lit "
            "pixels (its histogram has no two peaks)"
        )
    valley = int(np.argmin(hist[peaks[0] : peaks[1]])) + int(peaks[0])
    low, high = float(edges[valley + 1]), float(edges[peaks[1]])
    return low + BETWEEN * (high - low)


def lit_mask(
    black: NDArray[np.generic], white: NDArray[np.generic], threshold: float | None = None
) -> NDArray[np.bool_]:
    """Pixels whose white - black exceeds ``threshold`` (default :func:`lit_threshold`)
    and at least 4 of whose 9 x 9 neighbours do (specks removed)."""
    import cv2

    delta = np.asarray(white, np.float32) - np.asarray(black, np.float32)
    limit = lit_threshold(black, white) if threshold is None else threshold
    lit = np.nan_to_num(delta, nan=-np.inf) > limit
    kernel = np.full((VOTE_SIDE, VOTE_SIDE), 1.0 / VOTE_SIDE**2, np.float32)
    votes = cv2.filter2D(lit.astype(np.float32), -1, kernel)
    return np.asarray((votes > VOTE_COUNT / VOTE_SIDE**2) & lit, bool)


def largest_region(mask: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """The largest outer contour of ``mask``, filled (holes inside it included)."""
    import cv2

    contours = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)[0]
    if not contours:
        raise GlshadeError("black and white references: no pixel sees the lit screen")
    out = np.zeros(mask.shape, np.uint8)
    cv2.drawContours(out, [max(contours, key=cv2.contourArea)], -1, 255, cv2.FILLED)
    return out.astype(bool)
