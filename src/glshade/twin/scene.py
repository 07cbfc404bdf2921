"""The measured station as a glshade station scene (docs/twin.md): the camera posed by
OpenCV extrinsics with the station's intrinsics and distortion, the screen placed where
the station's calibration puts it (the flat rectangle nearest its calibrated shape),
and the facet's surface, nominal or fitted, in the facet's frame as SOFAST aligned it.

glshade's part frame has its surface ``y = f(x, z)``; SOFAST's facet frame has the
facet's normal along z. A facet point (x, y, z) is the part point (x, z, -y).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from glshade.capture.sofast import SofastMeasurement
from glshade.capture.sofast_station import SofastStation
from glshade.twin.reconstruct import FacetMeasurement

#: facet (x, y, z) -> part (x, z, -y)
FACET_TO_PART = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


@dataclass(frozen=True)
class TwinFrames:
    """The twin's geometry, every map a point takes: ``camera_from_part`` (R, t) with
    x_cam = R P + t; ``part_from_screen`` (R, t) with P = R s + t for a screen point s
    (mm, the station's screen coordinates); the flat screen's ``centre_s`` and
    ``half_size`` (mm) in screen coordinates; ``shape_rms_mm`` how far the calibrated
    screen departs from that flat rectangle."""

    camera_from_part: tuple[NDArray[np.float64], NDArray[np.float64]]
    part_from_screen: tuple[NDArray[np.float64], NDArray[np.float64]]
    centre_s: NDArray[np.float64]
    half_size: tuple[float, float]
    shape_rms_mm: float

    def screen_of_part(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """Part points (N, 3) in screen coordinates (N, 3)."""
        rot, shift = self.part_from_screen
        return np.asarray((points - shift) @ rot, np.float64)


def twin_frames(station: SofastStation, measured: FacetMeasurement) -> TwinFrames:
    """The frames of the aligned facet (the solver's alignment applied about the align
    point), the camera and the screen."""
    pose = measured.pose
    align = station.facet.centroid_mm
    alignment = measured.solution.alignment
    turn, shift = alignment[:3, :3], alignment[:3, 3]
    # aligned facet point q = turn (p - a) + a + shift, so p = turn^T (q - a - shift) + a
    cam_rot = pose.rotation @ turn.T @ FACET_TO_PART.T
    cam_t = pose.rotation @ (align - turn.T @ (align + shift)) + pose.translation_mm
    rot_sc, t_sc = station.screen_to_camera()
    # part P = M (turn (R^T (x_cam - t) - a) + a + shift), x_cam = R_sc s + t_sc
    to_facet = turn @ pose.rotation.T
    part_rot = FACET_TO_PART @ to_facet @ rot_sc
    part_t = FACET_TO_PART @ (
        to_facet @ (t_sc - pose.translation_mm) - turn @ align + align + shift
    )
    matrix, offset, rms = station.display.affine()
    centre = matrix @ np.array([0.5, 0.5]) + offset
    return TwinFrames(
        camera_from_part=(np.asarray(cam_rot, np.float64), np.asarray(cam_t, np.float64)),
        part_from_screen=(np.asarray(part_rot, np.float64), np.asarray(part_t, np.float64)),
        centre_s=np.array([centre[0], centre[1], 0.0]),
        half_size=(float(abs(matrix[0, 0])) / 2, float(abs(matrix[1, 1])) / 2),
        shape_rms_mm=rms,
    )


def surface_table(
    measured: FacetMeasurement, which: str, design_focal_mm: tuple[float, float]
) -> dict[str, Any]:
    """The facet's surface: ``"nominal"`` the design parabola, ``"fitted"`` SOFAST's
    fitted parabola (its tilt terms kept), as a formula in part coordinates (x, z = -y)."""
    if which == "nominal":
        fx, fy = design_focal_mm
        return {
            "kind": "formula",
            "expression": "x^2/(4*fx) + z^2/(4*fy)",
            "parameters": {"fx": fx, "fy": fy},
        }
    f, d, a, e, c, b = (float(v) for v in measured.solution.surface)
    return {
        "kind": "formula",
        "expression": "f0 + d*x + a*x^2 - e*z - c*x*z + b*z^2",
        "parameters": {"f0": f, "d": d, "a": a, "e": e, "c": c, "b": b},
    }


def twin_scene_dict(
    station: SofastStation,
    measurement: SofastMeasurement,
    measured: FacetMeasurement,
    surface: str = "nominal",
    design_focal_mm: tuple[float, float] = (100_000.0, 100_000.0),
    direction: str = "u",
    supersample: int = 1,
) -> dict[str, Any]:
    """The scene (as a scene file's tables) of the twin, showing the station's fringes
    along ``direction`` (u: the screen's x, v: its y) at its periods (the screen's extent
    / periods per screen, finest first) and shifts, phase zero where SOFAST's is (the
    screen's low x edge; its high y edge: the y scene's screen is turned over, its v axis
    the screen's -y), so the twin's frames are the station's, frame for frame;
    ``supersample`` rays per pixel side (the pixel's area integrated)."""
    import cv2

    frames = twin_frames(station, measured)
    cam_rot, cam_t = frames.camera_from_part
    part_rot, part_t = frames.part_from_screen
    centre = part_rot @ frames.centre_s + part_t
    normal = part_rot[:, 2]  # the screen's z in the part frame, turned to face the part
    if normal @ (np.zeros(3) - centre) < 0:
        normal = -normal
    # SOFAST's y fringes run from the screen's +y edge: v (and with it u) turned over
    up = part_rot[:, 1] if direction == "u" else -part_rot[:, 1]
    k = station.camera.matrix
    extent = 2 * frames.half_size[0 if direction == "u" else 1]
    per_screen = measurement.periods_x if direction == "u" else measurement.periods_y
    return {
        "camera": {
            "pose": "extrinsics",
            "rvec": [float(v) for v in cv2.Rodrigues(cam_rot)[0].ravel()],
            "tvec": [float(v) for v in cam_t],
            "intrinsics": [float(k[0, 0]), float(k[1, 1]), float(k[0, 2]), float(k[1, 2])],
            "distortion": [float(v) for v in station.camera.distortion[:5]],
            "width": int(station.camera.size[0]),
            "height": int(station.camera.size[1]),
        },
        "emitter": {
            "kind": "fringes",
            "pose": "placed",
            "centre": [float(v) for v in centre],
            "look_at": [float(v) for v in centre + normal],
            "up": [float(v) for v in up],
            "half_size": [frames.half_size[0], frames.half_size[1]],
            "periods": sorted(extent / p for p in per_screen),
            "shifts": int(measurement.shifts),
            "directions": [direction],
        },
        "surface": surface_table(measured, surface, design_focal_mm),
        "defect": {"dmax": 0.0},
        "render": {"supersample": int(supersample)},
    }
