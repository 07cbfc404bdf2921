"""Poses: where a station's camera, screen and part stand in one world frame (pyrr).

Conventions (``docs/stations.md``): the world frame is right-handed, in millimetres, ``+y``
up; a pose is a position and an orientation, the orientation a 3x3 matrix whose columns
are the device's own axes written in world coordinates (``world = position + M local``).

- **Angles** ``(yaw, pitch, roll)`` in degrees turn a device about its own axes, in that
  order (intrinsic ``y, x', z''``): ``M = M0 Ry(yaw) Rx(pitch) Rz(roll)``, each rotation
  right-handed (pyrr's ``create_from_{x,y,z}_rotation``: ``Ry(90°)`` takes ``+z`` to
  ``+x``). All three 0 leave ``M0`` untouched, bit for bit.
- **Own axes.** The camera: ``x`` image right, ``y`` image up, ``z`` backwards (it looks
  along ``-z``, OpenGL's camera); so positive yaw turns its view to the left, positive
  pitch raises it, positive roll turns the image counter-clockwise as the camera sees it.
  The screen: ``x = e_u``, ``y = e_v``, ``z`` its normal, towards the viewer. The part: the
  frame its surface ``y = f(x, z)`` is written in.
- **Look-at.** A device at ``eye`` aimed at ``target`` with an ``up`` hint: its axis is
  ``(target - eye) / |target - eye|``, its right ``axis x up`` (normalised), its up
  ``right x axis``.
- **OpenCV extrinsics** ``(rvec, tvec)`` as ``cv2.calibrateCamera`` returns them map world to
  camera, ``X_c = R X_w + t``, ``R = Rodrigues(rvec)``, camera ``x`` right, ``y`` down, ``z``
  forwards: the principal point is ``-Rᵀ t``, the rows of ``R`` are right, down and forward.

Everything is float64 NumPy.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

#: How close to parallel an axis and its up hint may be (|sin| of their angle) before the
#: look-at basis is refused as undefined.
MIN_UP_SINE = 1e-9


def pyrr_module() -> Any:
    """pyrr, imported on first use. Its source has an invalid escape sequence in a
    docstring, which Python 3.12 reports as a SyntaxWarning where it compiles the module
    itself (an install without byte-code): a dependency's note, kept off the user's screen."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", SyntaxWarning)
        import pyrr
    return pyrr


def rotation_ypr(yaw_deg: float, pitch_deg: float, roll_deg: float) -> np.ndarray:
    """``Ry(yaw) Rx(pitch) Rz(roll)``, float64 3x3, each right-handed about the device's
    own axis (intrinsic y, x', z''); exactly the identity when all three are 0."""
    turn = np.eye(3)
    if yaw_deg == 0.0 and pitch_deg == 0.0 and roll_deg == 0.0:
        return turn
    pyrr = pyrr_module()
    for make, angle in (
        (pyrr.matrix33.create_from_y_rotation, yaw_deg),
        (pyrr.matrix33.create_from_x_rotation, pitch_deg),
        (pyrr.matrix33.create_from_z_rotation, roll_deg),
    ):
        if angle != 0.0:
            turn = turn @ np.asarray(make(math.radians(angle)), dtype=np.float64)
    return turn


def turned(axes: np.ndarray, yaw_deg: float, pitch_deg: float, roll_deg: float) -> np.ndarray:
    """The orientation ``axes`` (3x3, columns = own axes in world) turned by ``(yaw,
    pitch, roll)`` about its own axes; ``axes`` itself when all three are 0."""
    if yaw_deg == 0.0 and pitch_deg == 0.0 and roll_deg == 0.0:
        return axes
    return axes @ rotation_ypr(yaw_deg, pitch_deg, roll_deg)


def look_at_axes(
    eye: np.ndarray, target: np.ndarray, up_hint: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """``(axis, right, up, distance)`` of a device at ``eye`` aimed at ``target``: unit
    float64 vectors and ``|target - eye|`` (mm). ValueError where ``eye`` is ``target`` or
    the axis is parallel to the up hint (the roll would be undefined)."""
    eye, target = np.asarray(eye, np.float64), np.asarray(target, np.float64)
    offset = target - eye
    distance = float(np.linalg.norm(offset))
    if not distance > 0.0 or not math.isfinite(distance):
        raise ValueError("it stands where it looks: the position and the look-at point coincide")
    axis = offset / distance
    side = np.cross(axis, np.asarray(up_hint, np.float64))
    size = float(np.linalg.norm(side))
    if size < MIN_UP_SINE * float(np.linalg.norm(up_hint)) or size == 0.0:
        raise ValueError("its up vector is parallel to its line of sight: the roll is undefined")
    right = side / size
    return axis, right, np.cross(right, axis), distance


def rodrigues(rvec: np.ndarray) -> np.ndarray:
    """OpenCV's rotation matrix of a Rodrigues vector (``cv2.Rodrigues``), float64 3x3."""
    import cv2

    matrix, _ = cv2.Rodrigues(np.asarray(rvec, np.float64).reshape(3, 1))
    return np.asarray(matrix, dtype=np.float64)


def rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The shortest rotation (3x3) taking the direction of ``a`` onto that of ``b``
    (``I + [v]x + [v]x² / (1 + c)``, ``v = a x b``, ``c = a . b``); refused for opposite
    directions, where no rotation is the shortest."""
    a = np.asarray(a, np.float64) / np.linalg.norm(a)
    b = np.asarray(b, np.float64) / np.linalg.norm(b)
    v = np.cross(a, b)
    c = float(a @ b)
    if c <= -1.0 + 1e-15:
        raise ValueError("rotation between opposite directions is not unique")
    vx = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.eye(3) + vx + (vx @ vx) / (1.0 + c)


def extrinsics_axes(
    rvec: np.ndarray, tvec: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(position, forward, right, up)`` of a camera given OpenCV's world-to-camera
    ``(rvec, tvec)`` (``tvec`` in mm), float64."""
    rotation = rodrigues(rvec)
    position = -rotation.T @ np.asarray(tvec, np.float64)
    return position, rotation[2].copy(), rotation[0].copy(), -rotation[1]


def to_extrinsics(
    position: np.ndarray, forward: np.ndarray, right: np.ndarray, up: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV's ``(rvec, tvec)`` of a camera pose (the inverse of :func:`extrinsics_axes`)."""
    import cv2

    rotation = np.stack([right, -np.asarray(up), forward]).astype(np.float64)
    rvec, _ = cv2.Rodrigues(rotation)
    return rvec.ravel(), -rotation @ np.asarray(position, np.float64)


@dataclass(frozen=True)
class Placement:
    """A rigid pose: ``world = position + axes @ local`` (mm; ``axes`` 3x3 float64, its
    columns the local axes in world coordinates)."""

    position: np.ndarray
    axes: np.ndarray

    @property
    def is_identity(self) -> bool:
        return not self.position.any() and bool((self.axes == np.eye(3)).all())

    def to_local_points(self, points: np.ndarray) -> np.ndarray:
        """World points (…, 3) in the local frame."""
        if self.is_identity:
            return points
        return (np.asarray(points, np.float64) - self.position) @ self.axes

    def to_local_vectors(self, vectors: np.ndarray) -> np.ndarray:
        """World directions (…, 3) in the local frame."""
        if self.is_identity:
            return vectors
        return np.asarray(vectors, np.float64) @ self.axes

    def to_world_points(self, points: np.ndarray) -> np.ndarray:
        if self.is_identity:
            return points
        return self.position + np.asarray(points, np.float64) @ self.axes.T

    def to_world_vectors(self, vectors: np.ndarray) -> np.ndarray:
        if self.is_identity:
            return vectors
        return np.asarray(vectors, np.float64) @ self.axes.T
