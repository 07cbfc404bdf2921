"""What a PMD station knows of itself and of the part it measures (:class:`StationModel`),
read once from a scene: the frames are rendered from the scene as it is (the truth),
decoding turns them into screen coordinates with the coding the screen shows, and slopes,
heights and the dent's fit turn those into geometry with what the station believes.

A real station decodes and reconstructs with what it believes of its geometry (its
calibration): the screen's plane, shape and cover glass, the camera's pose, intrinsics
and distortion, and the part's nominal shape (its CAD model). A scene's
``[calibration]`` table says where that belief differs from the truth
(:meth:`Scene.believed <glshade.scene.model.Scene.believed>`); without one the station
believes the truth, so a case's error is the station's method's, not its calibration's.

What is the truth's: the frames and the defect-free capture (:attr:`StationModel.truth`),
the coding the screen shows (its periods, shifts, directions and extent: the station
commands them), the sensor that records, and every comparison with the exact screen
points (decode failures, the dent's region, the window). What is the belief's: the
screen's plane, sag and glass a decoded point is placed on (:func:`screen_points`,
:func:`aimed_points`), the camera's rays and projection, and the nominal part.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from glshade.components.camera.perspective.table import Camera
from glshade.components.defect.gaussian.table import Defect
from glshade.components.emitter.fringes.table import DIRECTIONS, FringesTable, fringes_of
from glshade.components.emitter.plane import sag_coefficients, sag_height, sag_of
from glshade.components.sensor.linear.table import Sensor
from glshade.instruments.pmd.settings import check_scene
from glshade.metrics.status import dent_window
from glshade.rig import CameraPose, EmitterPlane
from glshade.scene import Scene

#: Fixed-point steps of :func:`aimed_points` through a believed cover glass: each shrinks
#: the error by about ``t / (n L)`` (1e-3 for a 1 mm glass 300 mm away), so from the
#: in-glass offset (< 1 mm) five leave far less than 1e-12 mm.
GLASS_STEPS = 5


@dataclass(frozen=True)
class StationModel:
    """A PMD station's model of itself and its part.

    The truth's: ``coding`` the screen's fringe coding (periods, shifts, directions,
    levels, the screen's extent: :class:`FringesTable` and its codec), ``axes`` the
    screen coordinates it codes (0: u, 1: v, in the order shown), ``sensor`` the sensor's
    table (None where the scene records radiance without one), ``truth`` the scene
    without its defect as it is (what the defect-free capture renders), ``window`` (H, W)
    the image's pixels near the dent.

    The belief's (:meth:`Scene.believed <glshade.scene.model.Scene.believed>`):
    ``screen`` the screen's plane in the world (mm), ``camera`` the camera's intrinsics
    and distortion and ``pose`` its principal point and axes, ``part`` the believed scene
    without its defect (the nominal surface the station takes each pixel's point on; its
    emitter table the screen's believed sag, glass and extent), ``defect`` where the dent
    is looked for (its centre and σ: the height grid's extent)."""

    coding: FringesTable
    axes: tuple[int, ...]
    screen: EmitterPlane
    camera: Camera
    pose: CameraPose
    sensor: Sensor | None
    part: Scene
    defect: Defect
    window: np.ndarray
    truth: Scene

    @property
    def half_period_mm(self) -> float:
        """Half the finest period (mm): a decoded point farther than this from the exact
        one was unwrapped onto another fringe."""
        return 0.5 * self.coding.periods[0]

    @property
    def sag(self) -> tuple[float, float, float] | None:
        """The screen's believed sag ``(bow_u, bow_v, twist)`` (mm), None: flat."""
        return sag_of(self.part)

    @property
    def glass(self) -> tuple[float, float] | None:
        """The screen's believed cover glass ``(thickness mm, index)``, None: none."""
        return self.part.active.emitter.cover_glass(self.part)


def station_model(scene: Scene) -> StationModel:
    """The station's model of ``scene``: its belief (:meth:`Scene.believed`; the scene's
    own geometry where it has no ``[calibration]``) and the truth it records; a scene a
    station cannot decode is refused in one line
    (:func:`~glshade.instruments.pmd.settings.check_scene`)."""
    check_scene(scene)
    believed = scene.believed()
    if believed is not scene:
        check_scene(believed)
    window = dent_window(scene, (scene.camera.height, scene.camera.width))
    screen, camera, pose = believed.emitter_plane(), believed.camera, believed.camera_pose()
    coding = fringes_of(scene)
    axes = tuple(DIRECTIONS.index(d) ^ 1 for d in coding.directions)
    sensor = scene.sensor if scene.active.records(scene) else None
    part = defect_free(believed)
    truth = part if believed is scene else defect_free(scene)
    return StationModel(
        coding, axes, screen, camera, pose, sensor, part, believed.defect, window, truth
    )


def defect_free(scene: Scene) -> Scene:
    """``scene`` without its dent as every dent at one place shares it: ``dmax = 0`` and
    the dent's shape at one fixed value (its centre kept: the renderer works in a frame
    centred on it). The defect-free capture, its noise and its analysis are then one for
    every dent's depth and width there (the trace without a dent does not depend on them;
    the noise is keyed by the scene)."""
    dent = replace(scene.defect, dmax=0.0, sigma_x2=1.0, sigma_z2=1.0, sigma_xz=0.0)
    return replace(scene, defect=dent)


def believed_uv(model: StationModel, uv: np.ndarray) -> np.ndarray:
    """Decoded screen coordinates ``uv`` (…, 2; mm from the centre of the screen as it
    is, the decoder's) from the believed centre: the coordinate along the screen from its
    edge is decoded, and the station believes the centre ``half_size`` from that edge."""
    shift = np.subtract(model.coding.half_size, model.part.emitter.half_size)
    return uv + shift if shift.any() else uv


def screen_points(model: StationModel, uv: np.ndarray) -> np.ndarray:
    """World points (mm) of screen coordinates ``uv`` (…, 2) on the model's screen: its
    believed plane, displaced along its normal by its believed sag ``w(u, v)`` (the
    emitting layer, under any cover glass)."""
    plane = model.screen
    uv = believed_uv(model, uv)
    points = plane.centre + uv[..., :1] * plane.e_u + uv[..., 1:] * plane.e_v
    sag = model.sag
    if sag is None:
        return points
    coefficients = sag_coefficients(sag, model.part.emitter.half_size)
    w = sag_height(coefficients, uv[..., 0], uv[..., 1])
    return points + w[..., None] * plane.normal


def aimed_points(model: StationModel, points: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """The points (mm) the rays from the part's ``points`` (…, 3) leave towards to land at
    the screen coordinates ``uv`` (…, 2): the emitting layer's (:func:`screen_points`)
    where the station believes its screen bare; behind a believed cover glass, the point
    on the glass's front face whose ray refracts onto the layer at ``uv``, in the model of
    ``lib/emitter_plane.glsl``: the front face ``thickness + w`` above the plane at the
    same ``(u, v)``, the ray's offset inside it ``t x / (n cos r)``, ``x = (r·e_u,
    r·e_v)``, ``cos r = sqrt(1 - |x|² / n²)``. The ray's direction ``r`` is found by
    :data:`GLASS_STEPS` fixed-point steps from the layer's point."""
    layer = screen_points(model, uv)
    glass = model.glass
    if glass is None:
        return layer
    thickness, index = glass
    plane = model.screen
    p = np.asarray(points, np.float64)
    base = believed_uv(model, uv)
    sag = model.sag
    coefficients = None if sag is None else sag_coefficients(sag, model.part.emitter.half_size)
    aimed = layer
    for _ in range(GLASS_STEPS):
        r = aimed - p
        r = r / np.linalg.norm(r, axis=-1, keepdims=True)
        x = np.stack([r @ plane.e_u, r @ plane.e_v], axis=-1)
        cos_r = np.sqrt(np.maximum(1.0 - np.sum(x * x, axis=-1) / index**2, 0.0))
        front = base - thickness * x / (index * cos_r[..., None])
        lift = np.full(front.shape[:-1], thickness)
        if coefficients is not None:
            lift = lift + sag_height(coefficients, front[..., 0], front[..., 1])
        aimed = (
            plane.centre
            + front[..., :1] * plane.e_u
            + front[..., 1:] * plane.e_v
            + lift[..., None] * plane.normal
        )
    return aimed
