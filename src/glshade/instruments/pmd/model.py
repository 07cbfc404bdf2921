"""What a PMD station knows of itself and of the part it measures (:class:`StationModel`),
read once from a scene: decoding, slopes and heights use it, the frames are rendered from
the scene itself.

A real station decodes and reconstructs with what it believes of its geometry (its
calibration): the screen's coding and plane, the camera's pose, intrinsics and
distortion, its sensor, and the part's nominal shape (its CAD model). glshade's station
believes the truth: the model is the scene's own geometry, so a case's error is the
station's method's, not its calibration's.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from glshade.components.camera.perspective.table import Camera
from glshade.components.defect.gaussian.table import Defect
from glshade.components.emitter.fringes.table import DIRECTIONS, FringesTable, fringes_of
from glshade.components.sensor.linear.table import Sensor
from glshade.instruments.pmd.settings import check_scene
from glshade.metrics.status import dent_window
from glshade.rig import CameraPose, EmitterPlane
from glshade.scene import Scene


@dataclass(frozen=True)
class StationModel:
    """A PMD station's model of itself and its part: ``coding`` the screen's fringe
    coding (periods, shifts, directions, levels: :class:`FringesTable` and its codec),
    ``axes`` the screen coordinates it codes (0: u, 1: v, in the order shown),
    ``screen`` the screen's plane in the world (mm), ``camera`` the camera's intrinsics
    and distortion and ``pose`` its principal point and axes, ``sensor`` the sensor's
    table (None where the scene records radiance without one), ``part`` the part without
    its defect (the nominal surface the station takes each pixel's point on), ``defect``
    where the dent is looked for (its centre and σ: the height grid's extent), ``window``
    (H, W) the image's pixels near the dent."""

    coding: FringesTable
    axes: tuple[int, ...]
    screen: EmitterPlane
    camera: Camera
    pose: CameraPose
    sensor: Sensor | None
    part: Scene
    defect: Defect
    window: np.ndarray

    @property
    def half_period_mm(self) -> float:
        """Half the finest period (mm): a decoded point farther than this from the exact
        one was unwrapped onto another fringe."""
        return 0.5 * self.coding.periods[0]


def station_model(scene: Scene) -> StationModel:
    """The station's model of ``scene``: its own geometry (a station that knows itself
    exactly); a scene a station cannot decode is refused in one line
    (:func:`~glshade.instruments.pmd.settings.check_scene`)."""
    check_scene(scene)
    window = dent_window(scene, (scene.camera.height, scene.camera.width))
    screen, camera, pose = scene.emitter_plane(), scene.camera, scene.camera_pose()
    coding = fringes_of(scene)
    axes = tuple(DIRECTIONS.index(d) ^ 1 for d in coding.directions)
    sensor = scene.sensor if scene.active.records(scene) else None
    part = scene.without_defect()
    return StationModel(coding, axes, screen, camera, pose, sensor, part, scene.defect, window)


def screen_points(model: StationModel, uv: np.ndarray) -> np.ndarray:
    """World points (mm) of screen coordinates ``uv`` (…, 2) on the model's screen."""
    plane = model.screen
    return plane.centre + uv[..., :1] * plane.e_u + uv[..., 1:] * plane.e_v
