"""The camera's table: where the camera is (elevation, the rig's azimuth, distance) and
what it is (focal length, sensor, thin lens, distortion); its pose from :mod:`glshade.rig`."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from glshade.components.camera.perspective.optics import check_distortion, undistort
from glshade.errors import SceneError
from glshade.params import Control, Table, param, point_param, turn_param
from glshade.poses import extrinsics_axes, look_at_axes, turned
from glshade.rig import CameraPose, camera_pose, rig_rotation

MAX_IMAGE_SIDE = 16384
#: How a camera is placed (``camera.pose``).
POSE_MODES = ("rig", "look_at", "extrinsics")

MAX_APERTURE_SAMPLES = 1024


#: The lowest elevation accepted (degrees, exclusive): below it the line of sight's sine
#: underflows in float32 (and, below 1e-308 degrees, in float64), and the camera lies in
#: the surface's plane.
MIN_THETA_DEG = 1e-3


def turned_pose(pose: CameraPose, yaw_deg: float, pitch_deg: float, roll_deg: float) -> CameraPose:
    """``pose`` turned about its own axes (:func:`glshade.poses.turned`; the camera's own
    axes are right, up and backwards); ``pose`` itself when all three angles are 0. It
    keeps its principal point, and aims at the point as far along its new axis."""
    if yaw_deg == 0.0 and pitch_deg == 0.0 and roll_deg == 0.0:
        return pose
    axes = turned(
        np.stack([pose.right, pose.up, -pose.forward], axis=1), yaw_deg, pitch_deg, roll_deg
    )
    right, up, forward = axes[:, 0], axes[:, 1], -axes[:, 2]
    target = pose.position + pose.distance * forward
    return CameraPose(pose.position, forward, right, up, target, pose.distance)


def check_pose(values: dict[str, Any]) -> None:
    """A camera table's pose keys agree with its ``pose`` mode."""
    mode = values["pose"]
    needs = {"rig": (), "look_at": (), "extrinsics": ("rvec", "tvec")}[mode]
    for key in needs:
        if values[key] is None:
            raise SceneError(
                f"camera.{key}", f'a list of 3 finite numbers (camera.pose = "{mode}")', None
            )
    allowed = {"rig": (), "look_at": ("position",), "extrinsics": ("rvec", "tvec")}[mode]
    for key in ("position", "rvec", "tvec"):
        if values[key] is not None and key not in allowed:
            wants = "look_at" if key == "position" else "extrinsics"
            raise SceneError(
                "camera.pose",
                f'"{wants}" where camera.{key} is given (it is ignored otherwise)',
                mode,
            )
    if mode == "look_at":
        given = values["position"]
        eye = (
            camera_pose(math.radians(values["theta_deg"]), math.radians(values["azimuth_deg"]),
                        values["distance"]).position
            if given is None
            else np.asarray(given, np.float64)
        )  # fmt: skip
        try:
            look_at_axes(eye, np.asarray(values["look_at"]), np.asarray(values["up"]))
        except ValueError as exc:
            key = (
                "up" if "up vector" in str(exc) else "position" if given is not None else "look_at"
            )
            raise SceneError(
                f"camera.{key}",
                f"a camera pose that can be built ({exc})",
                [float(x) for x in values[key]],
            ) from None
    if values["intrinsics"] is not None:
        fx, fy, _, _ = values["intrinsics"]
        if not (fx > 0.0 and fy > 0.0):
            raise SceneError(
                "camera.intrinsics",
                "[fx, fy, cx, cy] with fx, fy > 0 px",
                list(values["intrinsics"]),
            )


@dataclass(frozen=True)
class Camera(Table):
    """Where the camera is and what its sensor is (lengths in mm, angles in degrees)."""

    table = "camera"
    table_checks = (check_pose, check_distortion)

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

    pose: str = param(
        "camera.pose", "", "rig",
        'how the camera is placed: "rig" (the paper\'s: camera.theta_deg, camera.azimuth_deg '
        'and camera.distance about the origin), "look_at" (camera.position aimed at '
        'camera.look_at, camera.up its image up) or "extrinsics" (OpenCV\'s camera.rvec and '
        "camera.tvec, as cv2.calibrateCamera returns them); camera.yaw_deg, pitch_deg and "
        "roll_deg turn it further about its own axes",
        value_type="choice", choices=POSE_MODES, flag="--camera-pose", quiet=True,
    )  # fmt: skip
    position: tuple[float, float, float] | None = param(
        "camera.position", "mm", None,
        'the principal point in the world frame (camera.pose = "look_at"; unset: the '
        "rig's, from camera.theta_deg, azimuth_deg and distance)",
        value_type="vector", size=3,
    )  # fmt: skip
    look_at: tuple[float, float, float] = point_param(
        "camera.look_at",
        (0.0, 0.0, 0.0),
        'the point the optical axis aims at (camera.pose = "look_at")',
    )
    up: tuple[float, float, float] = point_param(
        "camera.up",
        (0.0, 1.0, 0.0),
        'the direction the image\'s up leans to (camera.pose = "look_at"; any length, not '
        "along the line of sight)",
        unit="",
    )
    yaw_deg: float = turn_param(
        "camera.yaw_deg",
        "turn of the camera about its own image-up axis after it is placed (positive: its "
        "view turns left); with pitch_deg and roll_deg, in that order",
    )
    pitch_deg: float = turn_param(
        "camera.pitch_deg",
        "turn of the camera about its own image-right axis (positive: its view rises)",
    )
    roll_deg: float = turn_param(
        "camera.roll_deg",
        "turn of the camera about its optical axis (positive: the image turns "
        "counter-clockwise as the camera sees it)",
    )
    rvec: tuple[float, float, float] | None = param(
        "camera.rvec", "rad", None,
        'OpenCV\'s world-to-camera rotation as a Rodrigues vector (camera.pose = "extrinsics")',
        value_type="vector", size=3,
    )  # fmt: skip
    tvec: tuple[float, float, float] | None = param(
        "camera.tvec", "mm", None,
        'OpenCV\'s world-to-camera translation (camera.pose = "extrinsics": X_cam = R X + t)',
        value_type="vector", size=3,
    )  # fmt: skip
    intrinsics: tuple[float, float, float, float] | None = param(
        "camera.intrinsics", "px", None,
        "OpenCV's camera matrix K as [fx, fy, cx, cy] in pixels (pixel centres at integers, "
        "as cv2.calibrateCamera returns it); unset: camera.focal over camera.pixel_pitch, "
        "the principal point at the sensor's centre. camera.focal stays the lens's focal "
        "length (its aperture)",
        value_type="vector", size=4,
    )  # fmt: skip

    @property
    def theta_rad(self) -> float:
        return math.radians(self.theta_deg)

    @property
    def azimuth_rad(self) -> float:
        return math.radians(self.azimuth_deg)

    @property
    def aim_distance(self) -> float:
        """The principal point's distance from the point it aims at (mm): the rig's
        ``distance``, a look-at camera's ``|look_at - position|``."""
        return self.world_pose().distance

    @property
    def pitch_xy(self) -> tuple[float, float]:
        """The sensor's pitch along x and y (mm per pixel at the focal length
        ``focal``): ``pixel_pitch`` twice, or ``focal / fx``, ``focal / fy`` of
        ``intrinsics``."""
        if self.intrinsics is None:
            return self.pixel_pitch, self.pixel_pitch
        fx, fy, _, _ = self.intrinsics
        return self.focal / fx, self.focal / fy

    @property
    def centre_px(self) -> tuple[float, float]:
        """Where the optical axis meets the sensor, in glshade's pixel coordinates (the
        top-left corner at (0, 0), pixel centres at half-integers): the sensor's centre,
        or OpenCV's ``(cx, cy)`` plus one half."""
        if self.intrinsics is None:
            return self.width * 0.5, self.height * 0.5
        _, _, cx, cy = self.intrinsics
        return cx + 0.5, cy + 0.5

    def world_pose(self, near: np.ndarray | None = None) -> CameraPose:
        """The principal point and the camera's unit axes in the world frame, as
        ``camera.pose`` places it (:mod:`glshade.poses`), turned by its yaw, pitch and
        roll. ``near``: for OpenCV extrinsics, the point (mm) the aim point is taken
        nearest to on the optical axis (the part's origin; default the world's)."""
        base = self.aimed_pose(near)
        return turned_pose(base, self.yaw_deg, self.pitch_deg, self.roll_deg)

    def aimed_pose(self, near: np.ndarray | None = None) -> CameraPose:
        """The camera's pose as placed, before its yaw, pitch and roll (where a "mirror"
        screen is put)."""
        if self.pose == "rig":
            base = camera_pose(self.theta_rad, self.azimuth_rad, self.distance)
        elif self.pose == "look_at":
            eye = (
                camera_pose(self.theta_rad, self.azimuth_rad, self.distance).position
                if self.position is None
                else np.asarray(self.position, np.float64)
            )
            target = np.asarray(self.look_at, np.float64)
            forward, right, up, distance = look_at_axes(eye, target, np.asarray(self.up))
            base = CameraPose(eye, forward, right, up, target, distance)
        else:
            position, forward, right, up = extrinsics_axes(
                np.asarray(self.rvec), np.asarray(self.tvec)
            )
            centre = np.zeros(3) if near is None else np.asarray(near, np.float64)
            distance = float((centre - position) @ forward)
            if not distance > 0.0:
                raise SceneError(
                    "camera.rvec", "a camera that looks towards the part (this one looks away)",
                    list(self.rvec or ()),
                )  # fmt: skip
            base = CameraPose(position, forward, right, up, position + distance * forward, distance)
        return base

    def rig_rotation(self) -> np.ndarray:
        """3x3 rotation of the rig (camera and emitter) about +y by ``azimuth_deg``: +z
        turns towards +x (float64); the identity at azimuth 0."""
        return rig_rotation(self.azimuth_rad)

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Unit vectors ``(forward, right, up)`` of the camera, float64."""
        pose = self.world_pose()
        return pose.forward, pose.right, pose.up

    def resampled(self, size: int) -> Camera:
        """The same field of view on ``size`` pixels across (``--size N``): the pitch
        becomes ``pixel_pitch * width / size``; the height keeps the aspect."""
        size = self.declaration("width").check(size)
        height = max(1, round(self.height * size / self.width))
        intrinsics = self.intrinsics
        if intrinsics is not None:
            k = size / self.width
            fx, fy, cx, cy = intrinsics
            intrinsics = (fx * k, fy * k, (cx + 0.5) * k - 0.5, (cy + 0.5) * k - 0.5)
        return replace(
            self, width=size, height=height, pixel_pitch=self.pixel_pitch * self.width / size,
            intrinsics=intrinsics,
        )  # fmt: skip

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
        (pitch_x, pitch_y), (cx, cy) = self.pitch_xy, self.centre_px
        sx = (j[None, :, None, None] + offset[None, None, None, :] - cx) * pitch_x
        sy = (cy - i[:, None, None, None] - offset[None, None, :, None]) * pitch_y
        sx, sy = np.broadcast_arrays(sx, sy)
        if any(self.distortion):
            x, y = undistort(self.distortion, sx / self.focal, -sy / self.focal)
            sx, sy = x * self.focal, -y * self.focal
        return sx, sy

    def pixel_rays(
        self,
        rows: slice | None = None,
        cols: slice | None = None,
        supersample: int = 1,
        pose: CameraPose | None = None,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(origin, directions)``, float64: ``origin`` the principal point (3,) in mm,
        unit ``directions`` (h, w, 3), or (h, w, n, n, 3) for ``n = supersample > 1``
        where ``[..., a, b, :]`` is the sub-pixel sample at ``((b + 0.5)/n, (a + 0.5)/n)``:
        the chief (pinhole) rays, distortion included. ``rows``/``cols`` select pixels of
        the full sensor (row 0 at the top). ``pose``: the camera's pose in the frame the
        rays are wanted in (default its world pose)."""
        sx, sy = self.sensor_offsets(rows, cols, supersample)
        pose = self.world_pose() if pose is None else pose
        forward, right, up = pose.forward, pose.right, pose.up
        d = self.focal * forward + sx[..., None] * right + sy[..., None] * up
        d = d / np.linalg.norm(d, axis=-1, keepdims=True)
        if supersample == 1:
            d = d[:, :, 0, 0, :]
        return pose.position, d
