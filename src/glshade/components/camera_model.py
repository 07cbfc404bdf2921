"""The camera of SPEC §2 and §8.2: a pinhole, or a thin lens, with OpenCV lens distortion.

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

GLSL: ``camera.glsl`` (uniforms), ``camera_lens.glsl`` and ``camera_distortion.glsl``
when on, ``camera_ray.glsl`` (the rays).
Oracle: :meth:`CameraModel.pixel_rays` (pinhole rays) and :meth:`CameraModel.sample_rays`
(every ray of every pixel, lens and distortion included), float64.
"""

from __future__ import annotations

import math

import numpy as np

from glshade.components.base import CameraComponent
from glshade.errors import SceneError
from glshade.scene.params import Control, Param

MAX_IMAGE_SIDE = 16384
MAX_APERTURE_SAMPLES = 1024
#: Newton iterations of the distortion's inversion (quadratic convergence: 6 reach fp64
#: from the distorted point for any non-folding distortion; more cost nothing).
UNDISTORT_ITERATIONS = 10
#: The golden angle (rad) of Vogel's spiral.
GOLDEN_ANGLE = math.pi * (3.0 - math.sqrt(5.0))

THETA = Param(
    "camera.theta_deg",
    "deg",
    45.0,
    "elevation of the line of sight above the surface",
    lo=0.0,
    hi=90.0,
    flag="--theta",
    control=Control("theta", 0.5, 89.5, fmt="%.1f deg"),
)
AZIMUTH = Param(
    "camera.azimuth_deg",
    "deg",
    0.0,
    "azimuth of the rig (camera and emitter together) about the surface normal at the origin, +y: 0 puts the "
    "camera on +z (as in the paper), 90 on +x; turns the plane of incidence over the surface, its dent and a cylinder's axis",
    lo=-360.0,
    hi=360.0,
    closed=True,
    flag="--azimuth",
    control=Control("azimuth", -180.0, 180.0, fmt="%.1f deg"),
)
DISTANCE = Param(
    "camera.distance", "mm", 175.6, "origin (the gaze point) to the principal point", lo=0.0
)
FOCAL = Param("camera.focal", "mm", 25.0, "focal length", lo=0.0)
PITCH = Param("camera.pixel_pitch", "mm", 0.005, "sensor pixel pitch", lo=0.0)
WIDTH = Param(
    "camera.width", "px", 1024, "sensor width", value_type="integer", lo=1, hi=MAX_IMAGE_SIDE
)
HEIGHT = Param(
    "camera.height", "px", 1024, "sensor height", value_type="integer", lo=1, hi=MAX_IMAGE_SIDE
)
F_NUMBER = Param(
    "camera.f_number",
    "",
    0.0,
    "0: a pinhole; > 0: a thin lens of aperture diameter focal / f_number (depth of field: a point so mm away "
    "blurs into a disc of angular diameter A |so - sf| / (so sf))",
    lo=0.0,
    closed=True,
    role="feature",
    flag="--f-number",
    control=Control("f-number", 0.0, 64.0, fmt="f/%.1f"),
    allowed_text="a finite number >= 0 (0: pinhole)",
)
FOCUS = Param(
    "camera.focus_distance",
    "mm",
    None,
    "thin lens: distance along the optical axis of the plane in focus (unset: camera.distance, the surface at the "
    "gaze point; camera.distance + emitter.distance focuses on the stripes' mirror image)",
    lo=0.0,
    flag="--focus",
)
APERTURE_SAMPLES = Param(
    "camera.aperture_samples",
    "",
    64,
    "thin lens: rays per pixel sample over the aperture (Vogel spiral)",
    value_type="integer",
    lo=1,
    hi=MAX_APERTURE_SAMPLES,
    flag="--aperture-samples",
)
DISTORTION = Param(
    "camera.distortion",
    "",
    (0.0, 0.0, 0.0, 0.0, 0.0),
    "OpenCV lens distortion (k1, k2, p1, p2, k3) on normalised coordinates, as cv2.calibrateCamera returns it",
    value_type="vector",
    size=5,
    role="feature",
    flag="--distortion",
)


def sensor_half_extent(width: int, height: int, pitch: float, focal: float) -> tuple[float, float]:
    """Half the sensor's width and height in normalised coordinates (sensor mm / focal)."""
    return width * pitch / (2.0 * focal), height * pitch / (2.0 * focal)


def distort(coeffs, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """OpenCV's distortion of ideal normalised coordinates (``y`` down), float64."""
    k1, k2, p1, p2, k3 = coeffs
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    return (
        x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
        y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y,
    )


def distortion_jacobian(coeffs, x: np.ndarray, y: np.ndarray):
    """``(dxd/dx, dxd/dy = dyd/dx, dyd/dy)`` of :func:`distort` (the model's Jacobian is
    symmetric)."""
    k1, k2, p1, p2, k3 = coeffs
    r2 = x * x + y * y
    radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
    dradial = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)  # d radial / d r2
    a = radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x
    b = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y
    d = radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x
    return a, b, d


def undistort(coeffs, xd: np.ndarray, yd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The ideal normalised coordinates whose distortion is ``(xd, yd)``: Newton's method
    from the distorted point (the shader's method, in float64)."""
    x, y = np.array(xd, np.float64), np.array(yd, np.float64)
    for _ in range(UNDISTORT_ITERATIONS):
        fx, fy = distort(coeffs, x, y)
        a, b, d = distortion_jacobian(coeffs, x, y)
        ex, ey = fx - xd, fy - yd
        det = a * d - b * b
        x = x - (d * ex - b * ey) / det
        y = y - (a * ey - b * ex) / det
    return x, y


def distortion_fold(
    coeffs, half_x: float, half_y: float, angles: int = 90, steps: int = 1500
) -> float | None:
    """Where (an ideal radius) the distortion folds inside the sensor, or None.

    Along ``angles`` rays of ideal directions, from the centre outwards until the
    distorted point leaves the sensor's circumscribed circle, the map's Jacobian must
    stay positive: a zero means two ideal directions land on one pixel. A map that
    still has not left the sensor at ideal radius 20 (87° off axis) folds back too.
    """
    if not any(coeffs):
        return None
    corner = math.hypot(half_x, half_y) * 1.02
    limit = 20.0
    phi = np.linspace(0.0, 2.0 * math.pi, angles, endpoint=False)
    r = np.linspace(0.0, limit, steps * 8 + 1)[1:]
    x = r[:, None] * np.cos(phi)[None, :]
    y = r[:, None] * np.sin(phi)[None, :]
    xd, yd = distort(coeffs, x, y)
    a, b, d = distortion_jacobian(coeffs, x, y)
    inside = np.hypot(xd, yd) <= corner
    # the stretch of each ray before it first leaves the circle
    before_exit = np.cumprod(inside, axis=0).astype(bool)
    if before_exit[-1].any():
        return float(limit)
    bad = before_exit & (a * d - b * b <= 0.0)
    if bad.any():
        return float(r[np.argmax(bad.any(axis=1))])
    return None


def check_distortion(values: dict) -> None:
    coeffs = values["distortion"]
    half = sensor_half_extent(
        values["width"], values["height"], values["pixel_pitch"], values["focal"]
    )
    where = distortion_fold(coeffs, *half)
    if where is not None:
        angle = math.degrees(math.atan(where))
        raise SceneError(
            "camera.distortion",
            f"coefficients whose map does not fold inside the sensor (this one folds {angle:.1f}° off the axis, "
            "where two directions would land on one pixel)",
            list(coeffs),
        )


class CameraModel(CameraComponent):
    name = "camera"
    doc = "a pinhole or a thin lens at the principal point, looking at the origin, with OpenCV distortion"
    params = (
        THETA,
        AZIMUTH,
        DISTANCE,
        FOCAL,
        PITCH,
        WIDTH,
        HEIGHT,
        F_NUMBER,
        FOCUS,
        APERTURE_SAMPLES,
        DISTORTION,
    )
    checks = (check_distortion,)

    def features(self, scene):
        cam = scene.camera
        return {"aperture": cam.f_number > 0.0, "distortion": any(cam.distortion)}

    def glsl(self, variables):
        files = ["camera.glsl"]
        if variables["aperture"]:
            files.append("camera_lens.glsl")
        if variables["distortion"]:
            files.append("camera_distortion.glsl")
        return (*files, "camera_ray.glsl")

    def uniforms(self, scene, frame):
        cam = scene.camera
        forward, right, up = cam.basis()
        values = {
            "u_cam_dist": cam.distance,
            "u_local_origin": tuple(frame.origin),
            "u_cam_forward": tuple(forward),
            "u_cam_right": tuple(right),
            "u_cam_up": tuple(up),
            "u_focal": cam.focal,
            "u_pitch": cam.pixel_pitch,
            "u_size": (cam.width, cam.height),
        }
        if frame.variables["aperture"]:
            values.update(
                u_aperture_radius=aperture_radius(cam),
                u_focus=focus_distance(cam),
                u_aperture_samples=cam.aperture_samples,
            )
        if frame.variables["distortion"]:
            k1, k2, p1, p2, k3 = cam.distortion
            values.update(u_dist_radial=(k1, k2, k3), u_dist_tangential=(p1, p2))
        return values

    def image_from_v(self, scene):
        return scene.camera.f_number == 0.0

    def samples(self, scene) -> int:
        return scene.camera.aperture_samples if scene.camera.f_number > 0.0 else 1

    # ---------------------------------------------------------------- oracle
    def sensor_offsets(self, scene, rows=None, cols=None, supersample: int = 1):
        """Ideal sensor positions ``(sx, sy)`` (mm; x right, y up) of the pixel samples,
        indexed ``(i, j, a, b)``: distortion undone."""
        camera = scene.camera
        n = int(supersample)
        if n < 1:
            raise ValueError(f"supersample: must be >= 1, got {supersample!r}")
        i = np.arange(camera.height, dtype=np.float64)[rows if rows is not None else slice(None)]
        j = np.arange(camera.width, dtype=np.float64)[cols if cols is not None else slice(None)]
        offset = (np.arange(n, dtype=np.float64) + 0.5) / n
        pitch = camera.pixel_pitch
        sx = (j[None, :, None, None] + offset[None, None, None, :] - camera.width / 2.0) * pitch
        sy = (camera.height / 2.0 - i[:, None, None, None] - offset[None, None, :, None]) * pitch
        sx, sy = np.broadcast_arrays(sx, sy)
        if any(camera.distortion):
            x, y = undistort(camera.distortion, sx / camera.focal, -sy / camera.focal)
            sx, sy = x * camera.focal, -y * camera.focal
        return sx, sy

    def pixel_rays(self, scene, rows=None, cols=None, supersample: int = 1):
        """``(origin, directions)``, float64: ``origin`` the principal point (3,) in mm,
        unit ``directions`` (h, w, 3), or (h, w, n, n, 3) for ``n = supersample > 1``
        where ``[..., a, b, :]`` is the sub-pixel sample at ``((b + 0.5)/n, (a + 0.5)/n)``:
        the chief (pinhole) rays, distortion included."""
        camera = scene.camera
        sx, sy = self.sensor_offsets(scene, rows, cols, supersample)
        forward, right, up = camera.basis()
        d = camera.focal * forward + sx[..., None] * right + sy[..., None] * up
        d = d / np.linalg.norm(d, axis=-1, keepdims=True)
        if supersample == 1:
            d = d[:, :, 0, 0, :]
        return camera.position(), d

    def sample_rays(self, scene, rows=None, cols=None, supersample: int = 1):
        """Every ray of every pixel: ``(origins, directions)`` of shape (h, w, S, 3) with
        ``S = supersample² x aperture samples`` (sub-pixel sample major)."""
        camera = scene.camera
        if camera.f_number == 0.0:
            return super().sample_rays(scene, rows, cols, supersample)
        origin, chief = self.pixel_rays(scene, rows, cols, supersample)
        h, w = chief.shape[:2]
        chief = chief.reshape(h, w, supersample * supersample, 3)
        forward, right, up = camera.basis()
        disc = aperture_points(camera.aperture_samples) * aperture_radius(camera)  # (K, 2) mm
        lens = origin + disc[:, :1] * right + disc[:, 1:] * up  # (K, 3)
        focus = (
            origin + (focus_distance(camera) / (chief @ forward))[..., None] * chief
        )  # (h, w, s, 3)
        towards = focus[:, :, :, None, :] - lens[None, None, None, :, :]
        directions = towards / np.linalg.norm(towards, axis=-1, keepdims=True)
        origins = np.broadcast_to(lens[None, None, None], directions.shape)
        count = directions.shape[2] * directions.shape[3]
        return origins.reshape(h, w, count, 3), directions.reshape(h, w, count, 3)


def aperture_radius(camera) -> float:
    """Radius of the lens disc (mm): ``focal / (2 f_number)``."""
    return camera.focal / (2.0 * camera.f_number)


def focus_distance(camera) -> float:
    """The plane in focus (mm along the optical axis): ``focus_distance`` or the camera distance."""
    return camera.focus_distance if camera.focus_distance is not None else camera.distance


def aperture_points(count: int) -> np.ndarray:
    """Vogel's spiral on the unit disc: (count, 2), ``r = sqrt((k + 1/2)/count)``, ``φ = k · golden angle``."""
    k = np.arange(count, dtype=np.float64)
    r = np.sqrt((k + 0.5) / count)
    phi = k * GOLDEN_ANGLE
    return np.stack([r * np.cos(phi), r * np.sin(phi)], axis=-1)
