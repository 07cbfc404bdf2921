"""The perspective camera: a pinhole, or a thin lens, with OpenCV lens distortion.

- **Pinhole** (``f_number = 0``, the default): one ray per pixel (sample) through the
  principal point.
- **Thin lens** (``f_number > 0``): pbrt's perspective-camera model. The lens is a disc
  of diameter ``A = focal / f_number`` centred on the principal point, perpendicular to the
  optical axis; every ray of a pixel passes through the point where the pixel's pinhole
  ray meets the plane at ``focus_distance`` (mm along the axis; default: the camera
  distance, i.e. focused on the surface at the gaze point). ``aperture_samples`` points
  of the disc per pixel sample, on Vogel's golden-angle spiral
  (``r = R sqrt((k + 1/2)/K)``, ``φ = k · 137.5°``): deterministic and evenly spread for
  any count. The image is their mean (a defocused pixel), the uv map the mean of the
  samples that reach the emitter. A point ``so`` mm along a ray blurs into a disc of
  angular diameter ``A |so - sf| / (so sf)``.
- **Distortion** (``distortion = [k1, k2, p1, p2, k3]``, OpenCV's model on normalised
  coordinates, ``y`` down as in OpenCV): the distorted camera's pixel ``p`` shows what
  the ideal camera shows at ``cv2.undistortPoints(p)``; the shader and the oracle invert
  the model by Newton's method. A distortion whose map folds inside the sensor (two
  ideal directions would land on one pixel) is refused.

Table: :class:`~glshade.components.camera.perspective.table.Camera`. GLSL: ``camera.glsl``
(uniforms), ``lens.glsl`` and ``distortion.glsl`` when on, ``ray.glsl`` (the rays).
Oracle: :meth:`Perspective.pixel_rays` (pinhole rays) and :meth:`Perspective.sample_rays`
(every ray of every pixel, lens and distortion included), float64.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping

import numpy as np

from glshade.components.base import CameraComponent, SceneView, UniformContext
from glshade.components.camera.perspective.optics import (
    aperture_points,
    aperture_radius,
    focus_distance,
)
from glshade.components.camera.perspective.table import Camera


class Perspective(CameraComponent):
    name = "perspective"
    doc = (
        "a pinhole or a thin lens at the principal point, looking at the origin, with OpenCV "
        "distortion"
    )
    table = Camera

    def features(self, scene: SceneView) -> dict[str, Hashable]:
        cam = scene.camera
        return {"aperture": cam.f_number > 0.0, "distortion": any(cam.distortion)}

    def stripe_blur_mm(self, scene: SceneView) -> float:
        """How far a thin lens spreads one point of the emitter's mirror image (mm on the
        emitter; 0 for the pinhole): the blur disc's angular diameter ``A |so - sf| /
        (so sf)`` at ``so = camera.distance + emitter.distance``, times ``so`` (a flat
        mirror's geometry; a curved base changes it by its magnification)."""
        cam = scene.camera
        if cam.f_number <= 0.0:
            return 0.0
        so, sf = scene.gaze.camera_mm + scene.gaze.screen_mm, focus_distance(cam)
        return 2.0 * aperture_radius(cam) * abs(so - sf) / sf

    def warnings(self, scene: SceneView) -> tuple[str, ...]:
        blur = self.stripe_blur_mm(scene)
        if blur <= 0.0:
            return ()
        period = scene.active.emitter.finest_period_mm(scene)
        if blur <= 0.5 * period:
            return ()
        cam = scene.camera
        sharp = cam.f_number * blur / (0.5 * period)
        stripes = scene.gaze.camera_mm + scene.gaze.screen_mm
        return (
            f"camera.f_number = {cam.f_number:g}: the lens blurs each emitter point over "
            f"{blur:.3g} mm, more than half the {period:g} mm stripe period, so the stripes "
            f"lose contrast; use camera.f_number >= {sharp:.3g}, or focus on the stripes' "
            f"mirror image (camera.focus_distance = {stripes:g})",
        )

    def dimming(self, scene: SceneView) -> str | None:
        blur = self.stripe_blur_mm(scene)
        if blur <= 0.0:
            return None
        return f"defocus: f/{scene.camera.f_number:g} blurs each emitter point over {blur:.3g} mm"

    def glsl(self, variables: Mapping[str, Hashable]) -> tuple[str, ...]:
        files = ["camera.glsl"]
        if variables["aperture"]:
            files.append("lens.glsl")
        if variables["distortion"]:
            files.append("distortion.glsl")
        return (*files, "ray.glsl")

    def uniforms(self, scene: SceneView, context: UniformContext) -> dict[str, object]:
        cam = scene.camera
        pose = scene.camera_pose()
        values: dict[str, object] = {
            "u_camera_dist": pose.distance,
            "u_camera_local_origin": tuple(np.asarray(context.origin) - pose.target),
            "u_camera_forward": tuple(pose.forward),
            "u_camera_right": tuple(pose.right),
            "u_camera_up": tuple(pose.up),
            "u_camera_focal": cam.focal,
            "u_camera_pitch": cam.pitch_xy,
            "u_camera_centre": cam.centre_px,
        }
        if context.variables["aperture"]:
            values.update(
                u_camera_aperture_radius=aperture_radius(cam),
                u_camera_focus=focus_distance(cam),
                u_camera_aperture_samples=cam.aperture_samples,
            )
        if context.variables["distortion"]:
            k1, k2, p1, p2, k3 = cam.distortion
            values.update(
                u_camera_distortion_radial=(k1, k2, k3), u_camera_distortion_tangential=(p1, p2)
            )
        return values

    def shades_from_emitter_map(self, scene: SceneView) -> bool:
        return scene.camera.f_number == 0.0

    def samples(self, scene: SceneView) -> int:
        return scene.camera.aperture_samples if scene.camera.f_number > 0.0 else 1

    # ---------------------------------------------------------------- oracle
    def pixel_rays(
        self,
        scene: SceneView,
        rows: slice | None = None,
        cols: slice | None = None,
        supersample: int = 1,
    ) -> tuple[np.ndarray, np.ndarray]:
        """The chief (pinhole) rays: :meth:`Camera.pixel_rays
        <glshade.components.camera.perspective.table.Camera.pixel_rays>`."""
        return scene.camera.pixel_rays(rows, cols, supersample, pose=scene.camera_pose())

    def sample_rays(
        self,
        scene: SceneView,
        rows: slice | None = None,
        cols: slice | None = None,
        supersample: int = 1,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Every ray of every pixel: ``(origins, directions)`` of shape (h, w, S, 3) with
        ``S = supersample² x aperture samples`` (sub-pixel sample major)."""
        camera = scene.camera
        if camera.f_number == 0.0:
            return super().sample_rays(scene, rows, cols, supersample)
        origin, chief = self.pixel_rays(scene, rows, cols, supersample)
        h, w = chief.shape[:2]
        chief = chief.reshape(h, w, supersample * supersample, 3)
        pose = scene.camera_pose()
        forward, right, up = pose.forward, pose.right, pose.up
        disc = aperture_points(camera.aperture_samples) * aperture_radius(camera)  # (K, 2) mm
        lens = origin + disc[:, :1] * right + disc[:, 1:] * up  # (K, 3)
        focus = origin + (focus_distance(camera) / (chief @ forward))[..., None] * chief
        towards = focus[:, :, :, None, :] - lens[None, None, None, :, :]
        directions = towards / np.linalg.norm(towards, axis=-1, keepdims=True)
        origins = np.broadcast_to(lens[None, None, None], directions.shape)
        count = directions.shape[2] * directions.shape[3]
        return origins.reshape(h, w, count, 3), directions.reshape(h, w, count, 3)


COMPONENTS = (Perspective,)
