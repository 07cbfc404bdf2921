"""What a glossy finish leaves of a fringe: the closed form of the modulation a reflection
lobe keeps (docs/physics.md, "Fringes on a glossy finish").

A reflection model with a lobe maps it onto the emitter, linearised about the mirror ray, as
a footprint matrix ``F`` (mm): a lobe offset ``x`` of its unit kernel (``gaussian``: ``x ~
N(0, I)``; ``ggx``: density ``1 / (π (1 + |x|²)²)``) lands at ``uv + F x``
(:meth:`ReflectionComponent.footprint
<glshade.components.base.ReflectionComponent.footprint>`). A fringe of period ``P`` along the
screen coordinate ``a`` changes only with ``row_a · x`` (``row_a`` the footprint's row of
``a``), whose law is the kernel's marginal at scale ``s = |row_a|``; each harmonic of the
fringe keeps the kernel's characteristic function at its frequency:

    B / B0 = T(2π s / P),   T(k) = exp(-k² / 2)   (Gaussian: B / B0 = exp(-2π² s² / P²))
                            T(k) = k K1(k)        (GGX, whose slopes have no variance)

``s`` is the lobe's standard deviation on the screen along the coded direction for the
Gaussian lobes (Blinn-Phong, Beckmann) and its scale for GGX. The shader's closed-form lobes
compute exactly this; the lattice and sampled ones integrate the exact lobe, which the form
describes while the lobe stays small against the screen distance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from glshade.scene import Scene


def kernel_transfer(kernel: str, k: np.ndarray) -> np.ndarray:
    """The characteristic function of the unit kernel's marginal at angular frequency ``k``
    (per unit of the kernel's variable): ``exp(-k²/2)`` (gaussian) or ``k K1(k)`` (ggx, 1 at
    0)."""
    k = np.abs(np.asarray(k, np.float64))
    if kernel == "gaussian":
        return np.exp(-0.5 * k * k)
    from scipy.special import k1

    with np.errstate(invalid="ignore", over="ignore"):
        return np.where(k > 0.0, k * k1(np.where(k > 0.0, k, 1.0)), 1.0)


@dataclass(frozen=True)
class LobeFootprint:
    """A lobe's footprint on the emitter for each pixel: ``matrix`` (H, W, 2, 2) mm, NaN
    where the pixel's ray meets no surface or lands off the emitter; ``kernel`` its unit
    kernel; ``finish`` the finish in words."""

    matrix: np.ndarray
    kernel: str
    finish: str

    def scale_mm(self, axis: int) -> np.ndarray:
        """``|row_axis|`` (H, W): the lobe's spread along screen coordinate ``axis`` (0: u,
        1: v), mm: a standard deviation for a Gaussian kernel, GGX's scale."""
        return np.linalg.norm(self.matrix[..., axis, :], axis=-1)

    def modulation(self, axis: int, period_mm: float) -> np.ndarray:
        """``B / B0`` (H, W): the share of a period-``period_mm`` fringe along ``axis`` the
        lobe keeps."""
        return kernel_transfer(self.kernel, 2.0 * math.pi * self.scale_mm(axis) / period_mm)

    def width_mm(self, axis: int) -> np.ndarray:
        """The lobe's ±1σ width along ``axis`` on the emitter (twice its scale), mm."""
        return 2.0 * self.scale_mm(axis)


def lobe_footprint(
    scene: Scene, rows: slice | None = None, cols: slice | None = None
) -> LobeFootprint | None:
    """The footprint of ``scene``'s reflection lobe for each pixel's chief ray (its centre,
    through the pinhole; ``rows``/``cols`` a window of the image), or None where the model
    has no lobe."""
    from glshade.oracle.tracer import first_hit  # a lobe only: most scenes never trace here

    reflection = scene.active.reflection
    origin, directions = scene.active.camera.pixel_rays(scene, rows, cols, 1)
    shape = directions.shape[:2]
    d = np.asarray(directions, np.float64).reshape(-1, 3)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    o = np.broadcast_to(np.asarray(origin, np.float64), d.shape)
    _, points, normals, valid = first_hit(scene, np.ascontiguousarray(o), d)
    valid = valid.reshape(-1)
    matrix = np.full((len(d), 2, 2), np.nan)
    if valid.any():
        p, n = points.reshape(-1, 3)[valid], normals.reshape(-1, 3)[valid]
        found = reflection.footprint(scene, p, d[valid], n)
        if found is None:
            return None
        matrix[valid], kernel = found
    else:
        probe = reflection.footprint(scene, np.zeros((1, 3)), -np.eye(3)[1:2], np.eye(3)[1:2])
        if probe is None:
            return None
        kernel = probe[1]
    return LobeFootprint(matrix.reshape(*shape, 2, 2), kernel, reflection.finish_name(scene))
