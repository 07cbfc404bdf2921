"""The rig: where the camera and the stripe emitter stand, as transforms (pyrr).

One place holds every pose of the scene's geometry (world frame of the docs: the gaze
point at the origin, ``+y`` up, the plane of incidence ``yz``, camera on ``+z``, emitter on
``-z``):

- the rig's azimuth: a rotation about ``+y`` that turns camera and emitter together
  (``+z`` towards ``+x``), the identity at azimuth 0;
- the camera's pose: principal point ``C = D R (0, sin θ, cos θ)``, ``forward = -C/|C|``,
  image up ``R (0, cos θ, -sin θ)``, right ``forward x up``;
- the emitter's plane: centre ``E = De R (0, sin θ, -cos θ)`` (the camera's mirror
  position), normal ``-E/|E|``, in-plane axes ``e_u = R (1, 0, 0)``, ``e_v = R (0, cos θ,
  sin θ)``;
- the viewer's orbit: a mouse drag turned into a new elevation and azimuth.

Everything is float64 NumPy; the matrices are pyrr's (column-vector convention:
``matrix @ vector``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from glshade.poses import Placement, pyrr_module

#: The elevation the orbit keeps the camera within (degrees above the surface).
ORBIT_THETA_DEG = (0.5, 89.5)


def rig_rotation(azimuth_rad: float) -> np.ndarray:
    """Rotation about +y by ``azimuth_rad`` (+z towards +x), float64 3x3; exactly the
    identity at 0."""
    if azimuth_rad == 0.0:
        return np.eye(3)
    pyrr = pyrr_module()  # only a turned rig needs it: most scenes never load it

    return np.asarray(pyrr.matrix33.create_from_y_rotation(azimuth_rad), dtype=np.float64)


@dataclass(frozen=True)
class CameraPose:
    """The camera's principal point (mm) and unit axes, float64 (3,) each; ``target`` the
    point of its optical axis it aims at and ``distance`` (mm) the principal point's
    distance from it (``position = target - distance forward``): the shader forms each
    ray's origin from these two, so no principal-point-sized number is ever subtracted
    from another (the rig: the origin, ``camera.distance``)."""

    position: np.ndarray
    forward: np.ndarray
    right: np.ndarray
    up: np.ndarray
    target: np.ndarray = field(default_factory=lambda: np.zeros(3))
    distance: float = 0.0

    def in_frame(self, frame: Placement) -> CameraPose:
        """The same pose in the local frame of ``frame`` (itself for the identity)."""
        if frame.is_identity:
            return self
        points, vectors = frame.to_local_points, frame.to_local_vectors
        return CameraPose(
            points(self.position), vectors(self.forward), vectors(self.right),
            vectors(self.up), points(self.target), self.distance,
        )  # fmt: skip


def camera_pose(theta_rad: float, azimuth_rad: float, distance_mm: float) -> CameraPose:
    """The camera at elevation ``theta_rad`` and rig azimuth ``azimuth_rad``,
    ``distance_mm`` from the gaze point, looking at it."""
    turn = rig_rotation(azimuth_rad)
    sin_t, cos_t = math.sin(theta_rad), math.cos(theta_rad)
    position = turn @ (distance_mm * np.array([0.0, sin_t, cos_t]))
    forward = turn @ -np.array([0.0, sin_t, cos_t])
    up = turn @ np.array([0.0, cos_t, -sin_t])
    return CameraPose(position, forward, np.cross(forward, up), up, np.zeros(3), distance_mm)


@dataclass(frozen=True)
class EmitterPlane:
    """The emitter's plane (float64): centre, unit normal (towards the viewer) and
    in-plane axes ``e_u``, ``e_v`` (``e_u x e_v = normal``); ``distance`` (mm) the plane's
    signed distance from the frame's origin (``x . normal = -distance`` on it) and
    ``offset_uv`` (mm) the centre's own ``(u, v)`` from the origin's foot: the shader finds
    a ray's screen point from these without subtracting the centre (the rig's screen:
    ``emitter.distance`` and ``(0, 0)``)."""

    centre: np.ndarray
    normal: np.ndarray
    e_u: np.ndarray
    e_v: np.ndarray
    distance: float = 0.0
    offset_uv: tuple[float, float] = (0.0, 0.0)

    def in_frame(self, frame: Placement) -> EmitterPlane:
        """The same plane in the local frame of ``frame`` (itself for the identity)."""
        if frame.is_identity:
            return self
        return placed_plane(
            frame.to_local_points(self.centre), frame.to_local_vectors(self.normal),
            frame.to_local_vectors(self.e_u), frame.to_local_vectors(self.e_v),
        )  # fmt: skip


def placed_plane(
    centre: np.ndarray, normal: np.ndarray, e_u: np.ndarray, e_v: np.ndarray
) -> EmitterPlane:
    """A plane through ``centre`` with its axes, its distance and offset worked out."""
    distance = -float(centre @ normal)
    return EmitterPlane(
        centre, normal, e_u, e_v, distance, (float(centre @ e_u), float(centre @ e_v))
    )


def emitter_plane(theta_rad: float, azimuth_rad: float, distance_mm: float) -> EmitterPlane:
    """The emitter in the camera's mirror position, ``distance_mm`` from the origin."""
    turn = rig_rotation(azimuth_rad)
    sin_t, cos_t = math.sin(theta_rad), math.cos(theta_rad)
    direction = turn @ np.array([0.0, sin_t, -cos_t])
    return EmitterPlane(
        centre=distance_mm * direction,
        normal=-direction,
        e_u=turn @ np.array([1.0, 0.0, 0.0]),
        e_v=turn @ np.array([0.0, cos_t, sin_t]),
        distance=distance_mm,
    )


@dataclass(frozen=True)
class Gaze:
    """The station's geometry at its gaze point, as the paper's closed forms read it:
    the elevation ``theta_rad`` of the camera above the part's tangent plane there, the
    azimuth ``azimuth_rad`` of the plane of incidence about the part's normal (``+z``
    towards ``+x``), the camera's distance ``camera_mm`` from it, the screen's distance
    ``screen_mm`` along the reflected line of sight, and the sensor's pitch ``pitch_mm``.
    For the rig they are ``camera.theta_deg``, ``azimuth_deg``, ``distance``,
    ``emitter.distance`` and ``pixel_pitch`` themselves."""

    theta_rad: float
    azimuth_rad: float
    camera_mm: float
    screen_mm: float
    pitch_mm: float


def orbit(
    theta_deg: float, azimuth_deg: float, dx_px: float, dy_px: float, deg_per_px: float = 0.25
) -> tuple[float, float]:
    """The elevation and azimuth after a mouse drag of ``(dx_px, dy_px)`` pixels: up
    raises the camera, right turns the rig; the elevation stays within
    :data:`ORBIT_THETA_DEG`, the azimuth within (-180, 180]."""
    lo, hi = ORBIT_THETA_DEG
    theta = min(hi, max(lo, theta_deg - dy_px * deg_per_px))
    azimuth = (azimuth_deg + dx_px * deg_per_px + 180.0) % 360.0 - 180.0
    return theta, (180.0 if azimuth == -180.0 else azimuth)


def orbit_position(
    position: np.ndarray, target: np.ndarray, dx_px: float, dy_px: float, deg_per_px: float = 0.25
) -> np.ndarray:
    """A posed camera's principal point after a mouse drag: it orbits ``target`` at its
    distance, its elevation above the plane through ``target`` (``+y`` up) and its azimuth
    about ``+y`` changed as :func:`orbit` changes the rig's (float64 (3,), mm)."""
    offset = np.asarray(position, np.float64) - np.asarray(target, np.float64)
    distance = float(np.linalg.norm(offset))
    theta = math.degrees(math.asin(max(-1.0, min(1.0, offset[1] / distance))))
    azimuth = math.degrees(math.atan2(offset[0], offset[2]))
    theta, azimuth = orbit(theta, azimuth, dx_px, dy_px, deg_per_px)
    t, a = math.radians(theta), math.radians(azimuth)
    along = np.array([math.cos(t) * math.sin(a), math.sin(t), math.cos(t) * math.cos(a)])
    return np.asarray(target, np.float64) + distance * along
