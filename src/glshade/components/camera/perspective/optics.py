"""The perspective camera's optics in float64: OpenCV's distortion model and its
inverse, the check that a distortion does not fold inside the sensor, and the thin lens's
aperture (Vogel's spiral). Used by the camera's table (its check) and its oracle."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from glshade.errors import SceneError


class Lens(Protocol):
    """What the lens's closed forms read of a camera table (mm; ``focus_distance`` None:
    the distance from the principal point to the point the camera aims at)."""

    @property
    def focal(self) -> float: ...
    @property
    def f_number(self) -> float: ...
    @property
    def focus_distance(self) -> float | None: ...
    @property
    def aim_distance(self) -> float: ...


#: Newton iterations of the distortion's inversion (quadratic convergence: 6 reach fp64
#: from the distorted point for any non-folding distortion; more cost nothing).
UNDISTORT_ITERATIONS = 10
#: The golden angle (rad) of Vogel's spiral.
GOLDEN_ANGLE = math.pi * (3.0 - math.sqrt(5.0))


def sensor_half_extent(width: int, height: int, pitch: float, focal: float) -> tuple[float, float]:
    """Half the sensor's width and height in normalised coordinates (sensor mm / focal)."""
    return width * pitch / (2.0 * focal), height * pitch / (2.0 * focal)


def distort(
    coeffs: Sequence[float], x: NDArray[np.float64], y: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """OpenCV's distortion of ideal normalised coordinates (``y`` down), float64."""
    k1, k2, p1, p2, k3 = coeffs
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    return (
        x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
        y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y,
    )


def distortion_jacobian(
    coeffs: Sequence[float], x: NDArray[np.float64], y: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """``(dxd/dx, dxd/dy = dyd/dx, dyd/dy)`` of :func:`distort` (the model's Jacobian is
    symmetric)."""
    k1, k2, p1, p2, k3 = coeffs
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    dradial = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)  # d radial / d r2
    a = radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x
    b = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y
    d = radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x
    return a, b, d


def undistort(
    coeffs: Sequence[float], xd: NDArray[np.float64], yd: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The ideal normalised coordinates whose distortion is ``(xd, yd)``: Newton's method
    from the distorted point (the shader's method, in float64)."""
    x, y = np.array(xd, np.float64), np.array(yd, np.float64)
    for _ in range(UNDISTORT_ITERATIONS):
        fx, fy = distort(coeffs, x, y)
        a, b, d = distortion_jacobian(coeffs, x, y)
        ex, ey = fx - xd, fy - yd
        det = a * d - b * b
        x = x - (d * ex - b * ey) / det
        y = y - (a * ey - b * ex) / det
    return x, y


def distortion_fold(
    coeffs: Sequence[float], half_x: float, half_y: float, angles: int = 90, steps: int = 1500
) -> float | None:
    """Where (an ideal radius) the distortion folds inside the sensor, or None.

    Along ``angles`` rays of ideal directions, from the centre outwards until the
    distorted point leaves the sensor's circumscribed circle, the map's Jacobian must
    stay positive: a zero means two ideal directions land on one pixel. A map that
    still has not left the sensor at ideal radius 20 (87° off axis) folds back too.
    """
    if not any(coeffs):
        return None
    corner = math.hypot(half_x, half_y) * 1.02
    limit = 20.0
    phi = np.linspace(0.0, 2.0 * math.pi, angles, endpoint=False)
    r = np.linspace(0.0, limit, steps * 8 + 1)[1:]
    x = r[:, None] * np.cos(phi)[None, :]
    y = r[:, None] * np.sin(phi)[None, :]
    xd, yd = distort(coeffs, x, y)
    a, b, d = distortion_jacobian(coeffs, x, y)
    inside = np.hypot(xd, yd) <= corner
    # the stretch of each ray before it first leaves the circle
    before_exit = np.cumprod(inside, axis=0).astype(bool)
    if before_exit[-1].any():
        return float(limit)
    bad = before_exit & (a * d - b * b <= 0.0)
    if bad.any():
        return float(r[np.argmax(bad.any(axis=1))])
    return None


def check_distortion(values: dict[str, Any]) -> None:
    """A camera table's distortion does not fold inside its sensor."""
    coeffs = values["distortion"]
    if values.get("intrinsics") is not None:
        fx, fy, cx, cy = values["intrinsics"]
        w, h = values["width"], values["height"]
        half = (max(cx + 0.5, w - cx - 0.5) / fx, max(cy + 0.5, h - cy - 0.5) / fy)
    else:
        half = sensor_half_extent(
            values["width"], values["height"], values["pixel_pitch"], values["focal"]
        )
    where = distortion_fold(coeffs, *half)
    if where is not None:
        angle = math.degrees(math.atan(where))
        raise SceneError(
            "camera.distortion",
            f"coefficients whose map does not fold inside the sensor (this one folds {angle:.1f}° "
            "off the axis, "
            "where two directions would land on one pixel)",
            list(coeffs),
        )


def aperture_radius(camera: Lens) -> float:
    """Radius of the lens disc (mm): ``focal / (2 f_number)``."""
    return camera.focal / (2.0 * camera.f_number)


def focus_distance(camera: Lens) -> float:
    """The plane in focus (mm along the optical axis): ``focus_distance`` or the camera distance."""
    return camera.focus_distance if camera.focus_distance is not None else camera.aim_distance


def aperture_points(count: int) -> NDArray[np.float64]:
    """Vogel's spiral on the unit disc: (count, 2), ``r = sqrt((k + 1/2)/count)``,
    ``φ = k · golden angle``."""
    k = np.arange(count, dtype=np.float64)
    r = np.sqrt((k + 0.5) / count)
    phi = k * GOLDEN_ANGLE
    return np.stack([r * np.cos(phi), r * np.sin(phi)], axis=-1)
