"""Small statistics the study's findings rest on."""

from __future__ import annotations

import numpy as np


def spearman(x, y) -> float:
    """Spearman's rank correlation (average ranks for ties); 0 when either is constant."""
    x, y = np.asarray(x, float), np.asarray(y, float)
    if len(x) < 2 or np.ptp(x) == 0 or np.ptp(y) == 0:
        return 0.0
    rx, ry = _ranks(x), _ranks(y)
    return float(np.corrcoef(rx, ry)[0, 1])


def _ranks(values: np.ndarray) -> np.ndarray:
    order = np.argsort(values, kind="mergesort")
    ranks = np.empty(len(values))
    ranks[order] = np.arange(len(values), dtype=float)
    for v in np.unique(values):
        same = values == v
        ranks[same] = ranks[same].mean()
    return ranks
