"""The pinhole camera of SPEC §2: elevation θ, distance, focal length, sensor.

GLSL: ``camera.glsl`` (the ray of a sensor position, re-originated near the dent).
Oracle: :meth:`Pinhole.pixel_rays`, the float64 rays of the same pixels.
"""

from __future__ import annotations

import numpy as np

from glshade.components.base import CameraComponent
from glshade.scene.params import Control, Param

MAX_IMAGE_SIDE = 16384

THETA = Param(
    "camera.theta_deg", "deg", 45.0, "elevation of the line of sight above the surface",
    lo=0.0, hi=90.0, flag="--theta", control=Control("theta", 0.5, 89.5, fmt="%.1f deg"),
)
DISTANCE = Param("camera.distance", "mm", 175.6, "origin (the gaze point) to the principal point", lo=0.0)
FOCAL = Param("camera.focal", "mm", 25.0, "focal length", lo=0.0)
PITCH = Param("camera.pixel_pitch", "mm", 0.005, "sensor pixel pitch", lo=0.0)
WIDTH = Param("camera.width", "px", 1024, "sensor width", value_type="integer", lo=1, hi=MAX_IMAGE_SIDE)
HEIGHT = Param("camera.height", "px", 1024, "sensor height", value_type="integer", lo=1, hi=MAX_IMAGE_SIDE)


class Pinhole(CameraComponent):
    name = "pinhole"
    doc = "an ideal pinhole at the principal point, looking at the origin"
    params = (THETA, DISTANCE, FOCAL, PITCH, WIDTH, HEIGHT)

    def glsl(self, variables):
        return ("camera.glsl",)

    def uniforms(self, scene, frame):
        cam = scene.camera
        forward, right, up = cam.basis()
        return {
            "u_cam_dist": cam.distance,
            "u_local_origin": tuple(frame.origin),
            "u_cam_forward": tuple(forward),
            "u_cam_right": tuple(right),
            "u_cam_up": tuple(up),
            "u_focal": cam.focal,
            "u_pitch": cam.pixel_pitch,
            "u_size": (cam.width, cam.height),
        }

    def pixel_rays(self, scene, rows=None, cols=None, supersample: int = 1):
        """``(origin, directions)``, float64: ``origin`` the principal point (3,) in mm,
        unit ``directions`` (h, w, 3), or (h, w, n, n, 3) for ``n = supersample > 1``
        where ``[..., a, b, :]`` is the sub-pixel sample at ``((b + 0.5)/n, (a + 0.5)/n)``."""
        camera = scene.camera
        n = int(supersample)
        if n < 1:
            raise ValueError(f"supersample: must be >= 1, got {supersample!r}")
        i = np.arange(camera.height, dtype=np.float64)[rows if rows is not None else slice(None)]
        j = np.arange(camera.width, dtype=np.float64)[cols if cols is not None else slice(None)]
        offset = (np.arange(n, dtype=np.float64) + 0.5) / n
        pitch = camera.pixel_pitch
        # sensor coordinates (mm), indexed (i, j, a, b)
        sx = (j[None, :, None, None] + offset[None, None, None, :] - camera.width / 2.0) * pitch
        sy = (camera.height / 2.0 - i[:, None, None, None] - offset[None, None, :, None]) * pitch
        forward, right, up = camera.basis()
        d = camera.focal * forward + sx[..., None] * right + sy[..., None] * up
        d = d / np.linalg.norm(d, axis=-1, keepdims=True)
        if n == 1:
            d = d[:, :, 0, 0, :]
        return camera.position(), d
