"""A facet's slopes from decoded screen points, reconstructed the way SOFAST's slope
solver does for a parabolic facet (docs/twin.md). Lengths in mm, slopes dz/dx, dz/dy.

The height-normal ambiguity is fixed by one distance: the measure point lies
``dist_optic_screen`` from the screen's origin. From a first parabola (the design's
focal lengths), four rounds of: three passes of (intersect the camera rays with the
current parabola, each pixel's normal the bisector of the directions to the camera and
to its screen point, a robust (Tukey bisquare) least-squares fit of a plane to each
slope, the parabola those planes integrate to); then the data turned about the align
point so the fitted normal there is the design's, and moved along the camera's line of
sight so the measure point's distance to the screen is the measured one. The final
slopes are the bisector normals at every pixel's intersection with the final parabola.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from glshade.errors import GlshadeError
from glshade.numerics import first_root_ahead, nearest_root
from glshade.poses import rotation_between

ROUNDS, PASSES = 4, 3
TUKEY_C, MAD_SCALE = 4.685, 0.6745


@dataclass(frozen=True)
class SlopeInputs:
    """What the solver needs, in facet coordinates (mm): ``rays`` (N, 3) the active
    pixels' unit directions, ``screen_mm`` (N, 3) their decoded screen points,
    ``camera_mm`` (3,), ``screen_origin_mm`` (3,) the screen's origin, ``measure_ray``
    (3,) the camera's unit ray through the measure point, ``align_mm`` (3,) the align
    point (the facet's centroid), ``distance_mm`` the measured measure point-screen
    distance, ``focal_mm`` (2,) the design focal lengths (x, y), ``downsample`` every
    n-th pixel used while aligning."""

    rays: NDArray[np.float64]
    screen_mm: NDArray[np.float64]
    camera_mm: NDArray[np.float64]
    screen_origin_mm: NDArray[np.float64]
    measure_ray: NDArray[np.float64]
    align_mm: NDArray[np.float64]
    distance_mm: float
    focal_mm: tuple[float, float]
    downsample: int = 10


@dataclass(frozen=True)
class SlopeSolution:
    """``slopes`` (2, N) dz/dx, dz/dy at ``points_mm`` (N, 3) on the fitted parabola;
    ``surface`` its coefficients (F, D, A, E, C, B) of z = F + D x + A x^2 + E y + C x y
    + B y^2 (mm); ``slope_coefs`` (2, 3) the planes (1, x, y) of dz/dx and dz/dy;
    ``alignment`` (4, 4) the rigid transform applied to the data about the align point."""

    slopes: NDArray[np.float64]
    points_mm: NDArray[np.float64]
    surface: NDArray[np.float64]
    slope_coefs: NDArray[np.float64]
    alignment: NDArray[np.float64]

    @property
    def focal_lengths_mm(self) -> tuple[float, float]:
        """The fitted parabola's focal lengths along x and y, 1 / (4 A), 1 / (4 B)."""
        return (1.0 / (4.0 * self.surface[2]), 1.0 / (4.0 * self.surface[5]))


def intersect(
    surface: NDArray[np.float64], rays: NDArray[np.float64], origin: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Points (N, 3) where the rays from ``origin`` first meet the parabola (the nearest
    root ahead, in the cancellation-free form)."""
    f, d, a, e, c, b = surface
    q, r, s = rays.T
    xc, yc, zc = origin
    qa = a * q**2 + b * r**2 + c * q * r
    qb = 2 * a * xc * q + 2 * b * yc * r + c * (xc * r + yc * q) + d * q + e * r - s
    qc = a * xc**2 + b * yc**2 + c * xc * yc + d * xc + e * yc + f - zc
    t = first_root_ahead(qa, 0.5 * qb, qc)
    if not np.all(np.isfinite(t)):
        raise GlshadeError("slope solver: a camera ray misses the facet's parabola")
    return origin + rays * t[:, None]


def bisector_slopes(
    points: NDArray[np.float64], camera: NDArray[np.float64], screen: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(2, N): each point's normal the bisector of its directions to the camera and to
    its screen point, as slopes -n_x / n_z, -n_y / n_z."""
    out = screen - points
    into = camera - points
    normal = out / np.linalg.norm(out, axis=1, keepdims=True)
    normal += into / np.linalg.norm(into, axis=1, keepdims=True)
    return np.stack([-normal[:, 0] / normal[:, 2], -normal[:, 1] / normal[:, 2]])


def robust_plane(
    values: NDArray[np.float64], points: NDArray[np.float64], weights: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(coefs (1, x, y), weights)``: iteratively reweighted least squares with Tukey's
    bisquare on leverage-adjusted residuals scaled by their MAD, until the mean residual
    norm changes by less than 1e-9 (SOFAST's robust fit)."""
    terms = np.stack([np.ones(len(points)), points[:, 0], points[:, 1]], axis=1)
    previous = 0.0
    coefs = np.zeros(3)
    for loop in range(1000):
        weighted = terms * weights[:, None]
        solve = np.linalg.lstsq(weighted.T @ terms, weighted.T, rcond=None)[0]
        coefs = solve @ values
        hat = (terms * solve.T).sum(axis=1)
        residual = values - terms @ coefs
        size = np.linalg.norm(residual) / len(values)
        if loop > 0 and abs(previous - size) < 1e-9:
            break
        previous = float(size)
        adjusted = residual / np.sqrt(1 - hat)
        spread = np.median(np.abs(adjusted - np.median(adjusted))) / MAD_SCALE
        scaled = adjusted / (TUKEY_C * spread)
        weights = (1 - scaled**2) ** 2
        weights[np.abs(scaled) >= 1] = 0
    return coefs, weights


def surface_of(coefs: NDArray[np.float64], align: NDArray[np.float64]) -> NDArray[np.float64]:
    """The parabola (F, D, A, E, C, B) whose slopes are the planes ``coefs`` (2, 3),
    its constant putting the align point on it."""
    cx, cy = coefs
    surface = np.array([0.0, cx[0], cx[1] / 2, cy[0], (cx[2] + cy[1]) / 2, cy[2] / 2])
    x, y = align[0], align[1]
    height = surface[1] * x + surface[2] * x * x + surface[3] * y
    height += surface[4] * x * y + surface[5] * y * y
    surface[0] = align[2] - height
    return surface


def solve(inputs: SlopeInputs) -> SlopeSolution:
    """The slopes of every active pixel (module docstring)."""
    fx, fy = inputs.focal_mm
    surface = np.array([0.0, 0.0, 1 / (4 * fx), 0.0, 0.0, 1 / (4 * fy)])
    rays = inputs.rays[:: inputs.downsample]
    screen = inputs.screen_mm[:: inputs.downsample].copy()
    camera = inputs.camera_mm.astype(np.float64).copy()
    origin = inputs.screen_origin_mm.astype(np.float64).copy()
    measure = inputs.measure_ray.astype(np.float64).copy()
    align = inputs.align_mm.astype(np.float64)
    weights = np.ones(len(rays))
    coefs = np.zeros((2, 3))
    alignment = np.eye(4)
    for _ in range(ROUNDS):
        for _ in range(PASSES):
            points = intersect(surface, rays, camera)
            slopes = bisector_slopes(points, camera, screen)
            fits = [robust_plane(slopes[i], points, weights.copy()) for i in range(2)]
            coefs = np.stack([fits[0][0], fits[1][0]])
            weights = np.minimum(fits[0][1], fits[1][1])
            surface = surface_of(coefs, align)
        measured = intersect(surface, measure[None], camera)[0]
        design = np.array([-align[0] / (2 * fx), -align[1] / (2 * fy), 1.0])
        at = np.array([1.0, align[0], align[1]])
        fitted = np.array([-coefs[0] @ at, -coefs[1] @ at, 1.0])
        turn = rotation_between(fitted, design)
        camera = turn @ (camera - align) + align
        screen = (screen - align) @ turn.T + align
        origin = turn @ (origin - align) + align
        rays = rays @ turn.T
        measure = turn @ measure
        # |origin + (camera - align) t - measured| = distance, t = scale - 1 nearest 0
        lever = camera - align
        gap = origin - measured
        t = nearest_root(
            float(lever @ lever), float(lever @ gap), float(gap @ gap) - inputs.distance_mm**2, 0.0
        )
        if not np.isfinite(t):
            raise GlshadeError("slope solver: no shift meets the measured distance")
        camera, screen, origin = camera + lever * t, screen + lever * t, origin + lever * t
        step = np.eye(4)
        step[:3, :3], step[:3, 3] = turn, lever * t
        alignment = step @ alignment
    return _final(inputs, surface, coefs, alignment, camera)


def _final(
    inputs: SlopeInputs,
    surface: NDArray[np.float64],
    coefs: NDArray[np.float64],
    alignment: NDArray[np.float64],
    camera: NDArray[np.float64],
) -> SlopeSolution:
    """Every pixel's slope on the final parabola, the data moved by ``alignment`` about
    the align point."""
    align = inputs.align_mm
    turn, shift = alignment[:3, :3], alignment[:3, 3]
    rays = inputs.rays @ turn.T
    screen = (inputs.screen_mm - align) @ turn.T + align + shift
    points = intersect(surface, rays, camera)
    return SlopeSolution(
        slopes=bisector_slopes(points, camera, screen),
        points_mm=points,
        surface=surface,
        slope_coefs=coefs,
        alignment=alignment,
    )
