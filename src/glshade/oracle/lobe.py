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

from glshade.components.reflection.kernels import half_frequency, kernel_transfer
from glshade.scene import Scene


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


@dataclass(frozen=True)
class FinishShare:
    """What the finish leaves of a fringe over some pixels: ``share`` (the median ``B /
    B0``), ``scale_mm`` (the lobe's median spread along the fringe's direction, mm),
    ``half_period_mm`` (the period it halves), ``axis`` (the direction, 0: u, 1: v) and
    ``finish`` (in words)."""

    share: float
    scale_mm: float
    half_period_mm: float
    axis: int
    finish: str

    def phrase(self, period_mm: float) -> str:
        """The finish as the cause of a washed-out fringe, in words."""
        kept = f"{self.share:.2g}" if self.share >= 1e-3 else "nothing"
        return (
            f"the finish ({self.finish}) spreads each screen point over "
            f"±{self.scale_mm:.3g} mm along {'uv'[self.axis]} and keeps {kept} of the "
            f"{period_mm:g} mm fringes' modulation (closed form); fringes of "
            f"{self.half_period_mm:.3g} mm keep half"
        )


def finish_share(
    scene: Scene, pixels: np.ndarray, period_mm: float, axes: tuple[int, ...]
) -> FinishShare | None:
    """The finish's share of a fringe of ``period_mm`` over ``pixels`` (H, W bool), along
    whichever of ``axes`` it keeps least of; None without a lobe or where no pixel's ray
    lands on the emitter."""
    rows, cols = np.flatnonzero(pixels.any(axis=1)), np.flatnonzero(pixels.any(axis=0))
    if not rows.size:
        return None
    window = (slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1))
    footprint = lobe_footprint(scene, *window)
    if footprint is None:
        return None
    inside = pixels[window]
    worst: FinishShare | None = None
    for axis in axes:
        scale = footprint.scale_mm(axis)[inside]
        scale = scale[np.isfinite(scale)]
        if not scale.size:
            continue
        median = float(np.median(scale))
        share = float(
            kernel_transfer(footprint.kernel, np.array(2.0 * math.pi * median / period_mm))
        )
        half = 2.0 * math.pi * median / half_frequency(footprint.kernel)
        found = FinishShare(share, median, half, axis, footprint.finish)
        if worst is None or found.share < worst.share:
            worst = found
    return worst


def gaze_share(scene: Scene, axis: int, periods: np.ndarray) -> np.ndarray:
    """What the finish's lobe keeps of each period along screen coordinate ``axis`` at the
    gaze point (the image's centre pixel): its kernel transfer at its scale there; 1 for a
    mirror, or where the centre ray meets no surface or lands off the emitter."""
    periods = np.asarray(periods, np.float64)
    cam = scene.camera
    centre = (
        slice(cam.height // 2, cam.height // 2 + 1),
        slice(cam.width // 2, cam.width // 2 + 1),
    )
    if scene.active.reflection.lobe_std_rad(scene) is None:
        return np.ones_like(periods)
    footprint = lobe_footprint(scene, *centre)
    if footprint is None:
        return np.ones_like(periods)
    scale = float(footprint.scale_mm(axis).reshape(-1)[0])
    if not math.isfinite(scale):
        return np.ones_like(periods)
    return kernel_transfer(footprint.kernel, 2.0 * math.pi * scale / periods)
