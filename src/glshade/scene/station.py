"""The station: the camera, the screen and the part posed in one world frame.

A scene places each of them by its own table (``camera.pose``, ``emitter.pose``,
``[part]``; :mod:`glshade.poses` for the conventions). The paper's rig is the default:
``camera.pose = "rig"`` puts the camera at elevation ``theta_deg`` and azimuth
``azimuth_deg``, ``distance`` from the origin, aimed at it; ``emitter.pose = "mirrored"``
puts the screen on the camera's line of sight reflected at the point it aims at, by a
mirror in the world's ``xz`` plane, ``emitter.distance`` from that point and facing it; the
part stands at the origin, unturned. The rig's poses come from the closed forms of
:mod:`glshade.rig`, so every rig scene renders bit for bit as before the poses existed.

The renderer, the oracle and the instruments work in the part's frame (where the surface
is ``y = f(x, z)``): :meth:`Scene.camera_pose` and :meth:`Scene.emitter_plane` bring the
camera and the screen into it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from glshade.errors import SceneError
from glshade.poses import Placement, look_at_axes, turned
from glshade.rig import CameraPose, EmitterPlane, Gaze, emitter_plane, placed_plane

#: The world's up: the normal of the mirror a "mirrored" screen is placed by.
WORLD_UP = np.array([0.0, 1.0, 0.0])


@dataclass(frozen=True)
class Station:
    """The camera and the screen in the world frame, and the part's placement in it."""

    camera: CameraPose
    screen: EmitterPlane
    part: Placement


def station_of(scene: Any) -> Station:
    """The poses of ``scene``'s camera, screen and part (world frame, float64)."""
    part = scene.part.placement()
    camera = scene.camera.world_pose(near=part.position)
    return Station(camera, screen_plane(scene, part), part)


def screen_plane(scene: Any, part: Placement) -> EmitterPlane:
    """The screen's plane in the world frame, as ``emitter.pose`` places it."""
    em, cam = scene.emitter, scene.camera
    if em.pose == "placed":
        rig = emitter_plane(cam.theta_rad, cam.azimuth_rad, em.distance)
        centre = rig.centre if em.centre is None else np.asarray(em.centre, np.float64)
        try:
            normal, right, up, _ = look_at_axes(centre, np.asarray(em.look_at), np.asarray(em.up))
        except ValueError as exc:
            on_up = "up vector" in str(exc)
            raise SceneError(
                "emitter.up" if on_up else "emitter.centre",
                f"a screen pose that can be built ({exc})",
                [float(x) for x in (em.up if on_up else centre)],
            ) from None
        e_u, e_v = -right, up
        plane = placed_plane(centre, normal, e_u, e_v)
    elif cam.pose == "rig":
        plane = emitter_plane(cam.theta_rad, cam.azimuth_rad, em.distance)
    else:
        plane = mirror_plane(cam.aimed_pose(near=part.position), em.distance)
    return turned_plane(plane, em.yaw_deg, em.pitch_deg, em.roll_deg)


def mirror_plane(camera: CameraPose, distance_mm: float) -> EmitterPlane:
    """The screen on ``camera``'s line of sight reflected at its aim point by a mirror in
    the world's ``xz`` plane, ``distance_mm`` from that point and facing it; its ``u``
    along the camera's image right."""
    forward = camera.forward
    reflected = forward - 2.0 * float(forward @ WORLD_UP) * WORLD_UP
    normal = -reflected
    side = camera.right - float(camera.right @ normal) * normal
    e_u = side / np.linalg.norm(side)
    return placed_plane(camera.target + distance_mm * reflected, normal, e_u, np.cross(normal, e_u))


def turned_plane(
    plane: EmitterPlane, yaw_deg: float, pitch_deg: float, roll_deg: float
) -> EmitterPlane:
    """``plane`` turned about its own axes ``(e_u, e_v, normal)`` around its centre;
    ``plane`` itself when all three angles are 0."""
    if yaw_deg == 0.0 and pitch_deg == 0.0 and roll_deg == 0.0:
        return plane
    axes = turned(
        np.stack([plane.e_u, plane.e_v, plane.normal], axis=1), yaw_deg, pitch_deg, roll_deg
    )
    return placed_plane(plane.centre, axes[:, 2], axes[:, 0], axes[:, 1])


def incidence_deg(camera: CameraPose, point: np.ndarray, normal: np.ndarray) -> float:
    """The angle of incidence (degrees from the normal) of the camera's ray at ``point``."""
    towards = np.asarray(camera.position, np.float64) - np.asarray(point, np.float64)
    cos_i = float(towards @ normal) / float(np.linalg.norm(towards) * np.linalg.norm(normal))
    return math.degrees(math.acos(max(-1.0, min(1.0, cos_i))))


def is_rig(scene: Any) -> bool:
    """The scene is the paper's rig: its camera and screen placed by the rig, unturned,
    over a part at the origin."""
    cam, em = scene.camera, scene.emitter
    turns = (cam.yaw_deg, cam.pitch_deg, cam.roll_deg, em.yaw_deg, em.pitch_deg, em.roll_deg)
    return (
        cam.pose == "rig"
        and em.pose == "mirrored"
        and not any(turns)
        and scene.part.placement().is_identity
        and cam.intrinsics is None
    )


def gaze_of(scene: Any) -> Gaze:
    """The :class:`Gaze` of ``scene``: the rig's own numbers, else those at the point
    where the camera's optical axis meets the part's tangent plane ``y = 0`` (its aim
    point where the axis never meets it), in the part's frame."""
    cam = scene.camera
    if is_rig(scene):
        return Gaze(
            cam.theta_rad, cam.azimuth_rad, cam.distance, scene.emitter.distance, cam.pixel_pitch
        )
    pose, plane = scene.camera_pose(), scene.emitter_plane()
    point = pose.target
    if pose.forward[1] < 0.0:
        point = pose.position - (pose.position[1] / pose.forward[1]) * pose.forward
    to_camera = pose.position - point
    camera_mm = float(np.linalg.norm(to_camera))
    seen = to_camera / camera_mm
    theta = math.asin(max(-1.0, min(1.0, float(seen[1]))))
    azimuth = math.atan2(float(seen[0]), float(seen[2]))
    reflected = -seen * np.array([1.0, -1.0, 1.0])
    facing = float(reflected @ plane.normal)
    gap = -plane.distance - float(point @ plane.normal)
    screen_mm = (
        gap / facing
        if facing < 0.0 and gap / facing > 0.0
        else float(np.linalg.norm(plane.centre - point))
    )
    pitch_x, pitch_y = cam.pitch_xy
    return Gaze(theta, azimuth, camera_mm, screen_mm, math.sqrt(pitch_x * pitch_y))
