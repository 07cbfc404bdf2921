"""The camera's table: where the camera is (elevation, the rig's azimuth, distance) and
what it is (focal length, sensor, thin lens, distortion); its pose from :mod:`glshade.rig`."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from glshade.components.camera.perspective.optics import check_distortion, undistort
from glshade.params import Control, Table, param
from glshade.rig import CameraPose, camera_pose, rig_rotation

MAX_IMAGE_SIDE = 16384
MAX_APERTURE_SAMPLES = 1024


#: The lowest elevation accepted (degrees, exclusive): below it the line of sight's sine
#: underflows in float32 (and, below 1e-308 degrees, in float64), and the camera lies in
#: the surface's plane.
MIN_THETA_DEG = 1e-3


@dataclass(frozen=True)
class Camera(Table):
    """Where the camera is and what its sensor is (lengths in mm, angles in degrees)."""

    table = "camera"
    table_checks = (check_distortion,)

    theta_deg: float = param(
        "camera.theta_deg", "deg", 45.0, "elevation of the line of sight above the surface",
        lo=MIN_THETA_DEG, hi=90.0, flag="--theta",
        control=Control("theta", 0.5, 89.5, fmt="%.1f deg"),
    )  # fmt: skip
    azimuth_deg: float = param(
        "camera.azimuth_deg", "deg", 0.0,
        "azimuth of the rig (camera and emitter together) about the surface normal at the "
        "origin, +y: 0 puts the camera on +z (as in the paper), 90 on +x; turns the plane of "
        "incidence over the surface, its dent and a cylinder's axis",
        lo=-360.0, hi=360.0, closed=True, flag="--azimuth",
        control=Control("azimuth", -180.0, 180.0, fmt="%.1f deg"),
    )  # fmt: skip
    distance: float = param(
        "camera.distance", "mm", 175.6, "origin (the gaze point) to the principal point", lo=0.0
    )
    focal: float = param("camera.focal", "mm", 25.0, "focal length", lo=0.0)
    pixel_pitch: float = param("camera.pixel_pitch", "mm", 0.005, "sensor pixel pitch", lo=0.0)
    width: int = param(
        "camera.width", "px", 1024, "sensor width", value_type="integer", lo=1, hi=MAX_IMAGE_SIDE
    )
    height: int = param(
        "camera.height", "px", 1024, "sensor height", value_type="integer", lo=1,
        hi=MAX_IMAGE_SIDE,
    )  # fmt: skip
    f_number: float = param(
        "camera.f_number", "", 0.0,
        "0: a pinhole; > 0: a thin lens of aperture diameter focal / f_number (depth of field: "
        "a point so mm away blurs into a disc of angular diameter A |so - sf| / (so sf))",
        lo=0.0, closed=True, role="feature", flag="--f-number",
        control=Control("f-number", 0.0, 64.0, fmt="f/%.1f"),
        allowed_text="a finite number >= 0 (0: pinhole)",
    )  # fmt: skip
    focus_distance: float | None = param(
        "camera.focus_distance", "mm", None,
        "thin lens: distance along the optical axis of the plane in focus (unset: "
        "camera.distance, the surface at the gaze point; camera.distance + emitter.distance "
        "focuses on the stripes' mirror image)",
        lo=0.0, flag="--focus",
    )  # fmt: skip
    aperture_samples: int = param(
        "camera.aperture_samples", "", 64,
        "thin lens: rays per pixel sample over the aperture (Vogel spiral)",
        value_type="integer", lo=1, hi=MAX_APERTURE_SAMPLES, flag="--aperture-samples",
    )  # fmt: skip
    exposure: float | str = param(
        "camera.exposure", "", "auto",
        "what the camera records of the radiance: recorded = radiance × exposure, full scale "
        "at 1 (exposure 1: the emitter's peak seen in a perfect mirror fills the range); "
        '"auto": the brightest emitter point the defect-free scene shows lands at 0.9 of the '
        "range. Scales what the sensor records (its photons, so its noise) and written "
        "images; the noiseless metric binarises radiance and does not depend on it",
        lo=0.0, keywords=("auto",), flag="--exposure",
    )  # fmt: skip
    distortion: tuple[float, float, float, float, float] = param(
        "camera.distortion", "", (0.0, 0.0, 0.0, 0.0, 0.0),
        "OpenCV lens distortion (k1, k2, p1, p2, k3) on normalised coordinates, as "
        "cv2.calibrateCamera returns it",
        value_type="vector", size=5, role="feature", flag="--distortion",
    )  # fmt: skip

    @property
    def theta_rad(self) -> float:
        return math.radians(self.theta_deg)

    @property
    def azimuth_rad(self) -> float:
        return math.radians(self.azimuth_deg)

    def rig_rotation(self) -> np.ndarray:
        """3x3 rotation of the rig (camera and emitter) about +y by ``azimuth_deg``: +z
        turns towards +x (float64); the identity at azimuth 0."""
        return rig_rotation(self.azimuth_rad)

    def pose(self) -> CameraPose:
        """The principal point and the camera's unit axes (:func:`glshade.rig.camera_pose`)."""
        return camera_pose(self.theta_rad, self.azimuth_rad, self.distance)

    def position(self) -> np.ndarray:
        """Principal point ``C = distance R (0, sin θ, cos θ)`` in mm (float64)."""
        return self.pose().position

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Unit vectors ``(forward, right, up)`` of the camera, float64."""
        pose = self.pose()
        return pose.forward, pose.right, pose.up

    def resampled(self, size: int) -> Camera:
        """The same field of view on ``size`` pixels across (``--size N``): the pitch
        becomes ``pixel_pitch * width / size``; the height keeps the aspect."""
        size = self.declaration("width").check(size)
        height = max(1, round(self.height * size / self.width))
        return replace(
            self, width=size, height=height, pixel_pitch=self.pixel_pitch * self.width / size
        )

    # ---------------------------------------------------------------- the oracle's rays
    def sensor_offsets(
        self, rows: slice | None = None, cols: slice | None = None, supersample: int = 1
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Ideal sensor positions ``(sx, sy)`` (mm; x right, y up) of the pixel samples,
        indexed ``(i, j, a, b)``: distortion undone."""
        n = int(supersample)
        if n < 1:
            raise ValueError(f"supersample: must be >= 1, got {supersample!r}")
        i = np.arange(self.height, dtype=np.float64)[rows if rows is not None else slice(None)]
        j = np.arange(self.width, dtype=np.float64)[cols if cols is not None else slice(None)]
        offset = (np.arange(n, dtype=np.float64) + 0.5) / n
        pitch = self.pixel_pitch
        sx = (j[None, :, None, None] + offset[None, None, None, :] - self.width / 2.0) * pitch
        sy = (self.height / 2.0 - i[:, None, None, None] - offset[None, None, :, None]) * pitch
        sx, sy = np.broadcast_arrays(sx, sy)
        if any(self.distortion):
            x, y = undistort(self.distortion, sx / self.focal, -sy / self.focal)
            sx, sy = x * self.focal, -y * self.focal
        return sx, sy

    def pixel_rays(
        self, rows: slice | None = None, cols: slice | None = None, supersample: int = 1
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(origin, directions)``, float64: ``origin`` the principal point (3,) in mm,
        unit ``directions`` (h, w, 3), or (h, w, n, n, 3) for ``n = supersample > 1``
        where ``[..., a, b, :]`` is the sub-pixel sample at ``((b + 0.5)/n, (a + 0.5)/n)``:
        the chief (pinhole) rays, distortion included. ``rows``/``cols`` select pixels of
        the full sensor (row 0 at the top)."""
        sx, sy = self.sensor_offsets(rows, cols, supersample)
        forward, right, up = self.basis()
        d = self.focal * forward + sx[..., None] * right + sy[..., None] * up
        d = d / np.linalg.norm(d, axis=-1, keepdims=True)
        if supersample == 1:
            d = d[:, :, 0, 0, :]
        return self.position(), d
