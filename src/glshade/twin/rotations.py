"""Small rotation and root helpers the twin's geometry shares (float64)."""

from __future__ import annotations

import math
from typing import SupportsFloat

import numpy as np
from numpy.typing import NDArray

from glshade.errors import GlshadeError


def rotvec_matrix(rvec: NDArray[np.float64]) -> NDArray[np.float64]:
    """The rotation matrix of a rotation vector (axis times angle, rad)."""
    theta = float(np.linalg.norm(rvec))
    if theta == 0.0:
        return np.eye(3)
    k = np.asarray(rvec, np.float64) / theta
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(theta) * kx + (1 - math.cos(theta)) * (kx @ kx)


def rotation_between(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    """The shortest rotation taking the direction of ``a`` onto that of ``b``."""
    a = np.asarray(a, np.float64) / np.linalg.norm(a)
    b = np.asarray(b, np.float64) / np.linalg.norm(b)
    v = np.cross(a, b)
    c = float(a @ b)
    if c <= -1.0 + 1e-15:
        raise GlshadeError("rotation between opposite directions is not unique")
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + (vx @ vx) / (1.0 + c)


def closest_root(a: SupportsFloat, b: SupportsFloat, c: SupportsFloat, near: float) -> float:
    """The real root of ``a x^2 + b x + c`` nearest ``near`` (cancellation-free form)."""
    a, b, c = float(a), float(b), float(c)
    disc = b * b - 4.0 * a * c
    if disc < 0:
        raise GlshadeError("no real solution: the distance cannot be met")
    q = -0.5 * (b + math.copysign(math.sqrt(disc), b))
    roots = [r for r in ((q / a) if a != 0 else math.nan, (c / q) if q != 0 else math.nan)]
    roots = [r for r in roots if math.isfinite(r)]
    if not roots:
        raise GlshadeError("no finite solution")
    return min(roots, key=lambda r: abs(r - near))
