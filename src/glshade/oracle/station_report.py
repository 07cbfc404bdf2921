"""A station's geometry in numbers (``glshade station``): how far the camera stands from
the dent and at what incidence, where the reflected chief ray meets the screen, how much of
the screen the camera's view uses and how finely it samples it.

Everything is float64 NumPy and comes from the oracle (:mod:`glshade.oracle.tracer`): the
dent is the defect-free surface at the defect's centre ``(x0, z0)`` (a vertical ray traced
down onto it gives its point and normal), the chief ray runs from the camera's principal
point to it, and the camera's pixels are traced on the defect-free scene (their chief rays,
reflected about the surface's normal, to the screen's plane). The numbers are worked out in
the part's frame (where the surface is ``y = f(x, z)``); points and normals are handed on
in the world frame (:attr:`Scene.station`), distances and angles being the same in both.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from glshade.errors import GlshadeError
from glshade.oracle.tracer import emitter_coordinates, first_hit, surface_height
from glshade.scene import Scene

#: Camera pixels traced along each side of the sensor for the screen's coverage.
COVERAGE_GRID = 64
#: How high above the dent (mm) the vertical ray that finds its normal starts.
_PROBE_HEIGHT_MM = 1.0
#: What the sampling line reports: screen pixels (a pixelated fringe screen) or mm.
SCREEN_PIXELS = "screen pixels per camera pixel"
SCREEN_MM = "screen mm per camera pixel"


def sensor_slice(pixels: int, count: int) -> slice:
    """At most ``count`` pixel indices spread evenly over ``pixels`` (every pixel where
    there are no more than ``count``), centred on the sensor."""
    step = max(1, -(-pixels // max(1, count)))
    samples = -(-pixels // step)
    start = (pixels - 1 - (samples - 1) * step) // 2
    return slice(start, pixels, step)


@dataclass(frozen=True)
class Traced:
    """Camera pixels traced on a scene (part frame, mm): the chief rays from ``origin``
    along ``directions`` (h, w, 3) for the pixels ``rows`` x ``cols`` of the sensor,
    whether each ``hit`` the surface, its hit ``points`` and ``reflected`` unit directions
    (NaN where no hit), where that reflected ray meets the screen's plane (``plane_points``,
    NaN where it never does, ``plane_t`` its distance from the hit), its screen ``uv``
    (h, w, 2; NaN where it is not ``on_screen``: the emitter's own test, its face, its
    rectangle) and whether it reaches the screen's rectangle ``from_behind``."""

    rows: np.ndarray
    cols: np.ndarray
    origin: np.ndarray
    directions: np.ndarray
    hit: np.ndarray
    points: np.ndarray
    reflected: np.ndarray
    plane_points: np.ndarray
    plane_t: np.ndarray
    uv: np.ndarray
    on_screen: np.ndarray
    from_behind: np.ndarray


def trace_pixels(scene: Scene, rows: slice, cols: slice) -> Traced:
    """The camera pixels ``rows`` x ``cols`` of ``scene`` traced to its surface and on to
    its screen (:class:`Traced`)."""
    origin, directions = scene.active.camera.pixel_rays(scene, rows, cols, 1)
    _, points, normals, hit = first_hit(scene, origin, directions)
    cos_i = np.einsum("...k,...k->...", directions, normals)
    reflected = directions - 2.0 * cos_i[..., None] * normals
    u, v, on_screen = emitter_coordinates(scene, points, reflected)
    plane = scene.emitter_plane()
    towards = reflected @ plane.normal
    with np.errstate(divide="ignore", invalid="ignore"):
        plane_t = -((points - plane.centre) @ plane.normal) / towards
    reaches = hit & (plane_t > 0.0) & np.isfinite(plane_t)
    plane_t = np.where(reaches, plane_t, np.nan)
    plane_points = points + plane_t[..., None] * reflected
    rel = plane_points - plane.centre
    hu, hv = scene.emitter.half_size
    inside = (np.abs(rel @ plane.e_u) <= hu) & (np.abs(rel @ plane.e_v) <= hv)
    height, width = scene.camera.height, scene.camera.width
    return Traced(
        rows=np.arange(height)[rows], cols=np.arange(width)[cols], origin=np.asarray(origin),
        directions=directions, hit=hit, points=points, reflected=reflected,
        plane_points=plane_points, plane_t=plane_t, uv=np.stack([u, v], axis=-1),
        on_screen=on_screen, from_behind=reaches & inside & (towards > 0.0),
    )  # fmt: skip


def trace_grid(scene: Scene, count: int) -> Traced:
    """About ``count`` x ``count`` camera pixels spread over the sensor, traced."""
    cam = scene.camera
    return trace_pixels(scene, sensor_slice(cam.height, count), sensor_slice(cam.width, count))


@dataclass(frozen=True)
class Dent:
    """The dent as the station sees it (part frame, mm): its point on the defect-free
    surface, the unit normal there, the chief ray's unit direction from the camera's
    principal point to it and its reflection about the normal."""

    point: np.ndarray
    normal: np.ndarray
    chief: np.ndarray
    reflected: np.ndarray


def dent_of(scene: Scene) -> Dent:
    """The dent of ``scene`` (a defect-free scene: its surface at the defect's centre)."""
    x0, _, z0 = (float(c) for c in scene.active.defect.centre(scene))
    height = float(surface_height(scene.surface, scene.defect, x0, z0))
    if not math.isfinite(height):
        raise GlshadeError(
            f"defect: its centre (x0, z0) = ({x0:g}, {z0:g}) mm must lie on the surface "
            "(it is outside the surface's domain)"
        )
    point = np.array([x0, height, z0])
    probe = np.array([x0, height + _PROBE_HEIGHT_MM, z0])
    _, _, normals, valid = first_hit(scene, probe, np.array([[0.0, -1.0, 0.0]]))
    if not valid[0]:
        raise GlshadeError(
            f"defect: the surface has no data at its centre (x0, z0) = ({x0:g}, {z0:g}) mm"
        )
    normal = normals[0]
    chief = point - scene.camera_pose().position
    chief = chief / np.linalg.norm(chief)
    return Dent(point, normal, chief, chief - 2.0 * float(chief @ normal) * normal)


@dataclass(frozen=True)
class StationReport:
    """The station's numbers (mm, degrees; ``None`` where a number does not exist).

    ``working_distance_mm``: principal point to the dent; ``aim_distance_mm``: principal
    point to the point the camera aims at; ``incidence_deg``: the chief ray's angle from
    the part's normal at the dent, ``elevation_deg`` its angle above the tangent plane
    there (90 - incidence); ``screen_distance_mm``: dent to the screen's plane along the
    reflected chief ray, ``chief_uv_mm`` where it lands on the screen (None where it misses
    the screen); ``coverage``: the share of the ``grid`` of traced pixels whose reflection
    lands on the screen, ``u_range_mm``/``v_range_mm`` the extent of the screen they use
    and ``u_share``/``v_share`` that extent over the screen's size; ``sampling`` the screen
    per camera pixel at the dent's image point along the image's x and y (``sampling_unit``
    says in what: :data:`SCREEN_PIXELS` or :data:`SCREEN_MM`; None where the dent is not in
    the image or its neighbours miss the screen, ``sampling_note`` says which);
    ``dent_pixel`` the dent's image point (row, col; pixel centres at integers)."""

    title: str
    working_distance_mm: float
    aim_distance_mm: float
    incidence_deg: float
    elevation_deg: float
    dent_world: tuple[float, float, float]
    normal_world: tuple[float, float, float]
    screen_distance_mm: float | None
    chief_uv_mm: tuple[float, float] | None
    grid: tuple[int, int]
    coverage: float
    u_range_mm: tuple[float, float]
    v_range_mm: tuple[float, float]
    u_share: float
    v_share: float
    screen_size_mm: tuple[float, float]
    sampling_unit: str
    sampling: tuple[float, float] | None
    sampling_note: str
    dent_pixel: tuple[float, float]

    @property
    def chief_on_screen(self) -> bool:
        return self.chief_uv_mm is not None

    def to_json(self) -> dict[str, Any]:
        """The numbers as JSON values (tuples as lists)."""
        return {
            "title": self.title,
            "working_distance_mm": self.working_distance_mm,
            "aim_distance_mm": self.aim_distance_mm,
            "incidence_deg": self.incidence_deg,
            "elevation_deg": self.elevation_deg,
            "dent_mm": list(self.dent_world),
            "normal_at_dent": list(self.normal_world),
            "screen_distance_mm": self.screen_distance_mm,
            "chief_ray_on_screen": self.chief_on_screen,
            "chief_uv_mm": None if self.chief_uv_mm is None else list(self.chief_uv_mm),
            "traced_pixels": list(self.grid),
            "coverage": self.coverage,
            "u_range_mm": list(self.u_range_mm),
            "v_range_mm": list(self.v_range_mm),
            "u_share": self.u_share,
            "v_share": self.v_share,
            "screen_size_mm": list(self.screen_size_mm),
            "sampling_unit": self.sampling_unit,
            "sampling": None if self.sampling is None else list(self.sampling),
            "sampling_note": self.sampling_note,
            "dent_pixel": [c if math.isfinite(c) else None for c in self.dent_pixel],
        }

    def lines(self) -> list[str]:
        """The numbers as an aligned text block, a unit on every line."""
        (su, sv), (gh, gw) = self.screen_size_mm, self.grid
        screen = "never: the reflected chief ray does not reach the screen's plane"
        if self.screen_distance_mm is not None:
            screen = f"{self.screen_distance_mm:.3f} mm, dent to the screen along the reflected ray"
        landing = "no: it misses the screen"
        if self.chief_uv_mm is not None:
            u, v = self.chief_uv_mm
            landing = f"yes, at (u, v) = ({u:.3f}, {v:.3f}) mm"
        sampled = f"n/a {self.sampling_unit} ({self.sampling_note})"
        if self.sampling is not None:
            x, y = self.sampling
            sampled = f"{x:.4g} x {y:.4g} {self.sampling_unit} (image x, y; at the dent)"
        rows = [
            ("working distance", f"{self.working_distance_mm:.3f} mm, camera to the dent"),
            ("aim distance", f"{self.aim_distance_mm:.3f} mm, camera to its aim point"),
            ("incidence", f"{self.incidence_deg:.3f} deg at the dent, from the part's normal"),
            ("elevation", f"{self.elevation_deg:.3f} deg above the tangent plane there"),
            ("screen distance", screen),
            ("chief ray on screen", landing),
            ("screen coverage", f"{100.0 * self.coverage:.1f} % of {gh}x{gw} traced pixels"),
            ("screen used in u", _used(self.u_range_mm, self.u_share, su)),
            ("screen used in v", _used(self.v_range_mm, self.v_share, sv)),
            ("screen sampling", sampled),
        ]
        width = max(len(label) for label, _ in rows)
        return [f"{label:<{width}}  {value}" for label, value in rows]


def _used(extent: tuple[float, float], share: float, size: float) -> str:
    return f"{extent[0]:.2f} .. {extent[1]:.2f} mm ({100.0 * share:.1f} % of {size:g} mm)"


def station_report(scene: Scene, grid: int = COVERAGE_GRID) -> StationReport:
    """The numbers of ``scene``'s station; a :class:`GlshadeError` (one line) where no
    traced pixel's reflection lands on the screen, or where the part shows the camera the
    screen's back."""
    free = scene.without_defect()
    station, pose = free.station, free.camera_pose()
    dent = dent_of(free)
    traced = trace_grid(free, grid)
    refuse_unseen(free, traced)
    offset = dent.point - pose.position
    cos_i = -float(dent.chief @ dent.normal)
    incidence = math.degrees(math.acos(max(-1.0, min(1.0, cos_i))))
    distance, uv = chief_landing(free, dent)
    seen = traced.uv[traced.on_screen]
    hu, hv = free.emitter.half_size
    u_range = (float(seen[:, 0].min()), float(seen[:, 0].max()))
    v_range = (float(seen[:, 1].min()), float(seen[:, 1].max()))
    unit, sampling, note, pixel = dent_sampling(free, dent)
    to_world = station.part
    return StationReport(
        title=scene.title(),
        working_distance_mm=float(np.linalg.norm(offset)),
        aim_distance_mm=float(station.camera.distance),
        incidence_deg=incidence,
        elevation_deg=90.0 - incidence,
        dent_world=_triple(to_world.to_world_points(dent.point)),
        normal_world=_triple(to_world.to_world_vectors(dent.normal)),
        screen_distance_mm=distance,
        chief_uv_mm=uv,
        grid=(len(traced.rows), len(traced.cols)),
        coverage=float(traced.on_screen.mean()),
        u_range_mm=u_range,
        v_range_mm=v_range,
        u_share=(u_range[1] - u_range[0]) / (2.0 * hu),
        v_share=(v_range[1] - v_range[0]) / (2.0 * hv),
        screen_size_mm=(2.0 * hu, 2.0 * hv),
        sampling_unit=unit,
        sampling=sampling,
        sampling_note=note,
        dent_pixel=pixel,
    )


def _triple(vector: np.ndarray) -> tuple[float, float, float]:
    x, y, z = (float(c) for c in vector)
    return x, y, z


def refuse_unseen(scene: Scene, traced: Traced) -> None:
    """One line where none of the ``traced`` pixels' reflections lands on the screen: a
    distinct one where they reach it from behind (its normal points away from the part)."""
    if traced.on_screen.any():
        return
    em = scene.emitter
    where = (
        f"emitter.pose = {em.pose}, centre {_shown(scene.station.screen.centre)} mm, "
        f"normal {_shown(scene.station.screen.normal)}"
    )
    total = traced.hit.size
    if traced.from_behind.any():
        raise GlshadeError(
            f"station: the screen is seen from behind: {int(traced.from_behind.sum())} of "
            f"{total} traced camera pixels reflect onto its back ({where}); its normal must "
            "point towards the part (emitter.look_at, emitter.yaw_deg)"
        )
    hits = int(traced.hit.sum())
    why = "none of them hits the part" if not hits else f"{hits} hit the part"
    raise GlshadeError(
        f"station: no camera pixel sees the screen: of {total} traced pixels {why} and no "
        f"reflection lands on the screen ({where}); move the screen or the camera"
    )


def _shown(vector: np.ndarray) -> str:
    return "(" + ", ".join(f"{float(c):.4g}" for c in vector) + ")"


def chief_landing(scene: Scene, dent: Dent) -> tuple[float | None, tuple[float, float] | None]:
    """The distance (mm) from the dent to the screen's plane along the reflected chief ray
    (None where it never reaches the plane: the camera below the tangent plane, or the ray
    parallel to or away from the plane) and its screen ``(u, v)`` (mm; None where it
    misses the screen)."""
    if float(dent.chief @ dent.normal) >= 0.0:  # the camera looks at the part from below
        return None, None
    plane = scene.emitter_plane()
    towards = float(dent.reflected @ plane.normal)
    along = -float((dent.point - plane.centre) @ plane.normal)
    distance = along / towards if towards != 0.0 else math.nan
    u, v, ok = emitter_coordinates(scene, dent.point[None, :], dent.reflected[None, :])
    landing = (float(u[0]), float(v[0])) if ok[0] else None
    return (distance if distance > 0.0 else None), landing


def image_point(scene: Scene, point: np.ndarray) -> tuple[float, float]:
    """Where the camera images ``point`` (part frame, mm): ``(row, col)``, pixel centres
    at integers (its distortion included); NaN behind the camera."""
    from glshade.components.camera.perspective.optics import distort

    cam, pose = scene.camera, scene.camera_pose()
    offset = np.asarray(point, np.float64) - pose.position
    depth = float(offset @ pose.forward)
    if not depth > 0.0:
        return math.nan, math.nan
    x, y = float(offset @ pose.right) / depth, -float(offset @ pose.up) / depth
    if any(cam.distortion):
        xd, yd = distort(cam.distortion, np.array(x), np.array(y))
        x, y = float(xd), float(yd)
    (pitch_x, pitch_y), (cx, cy) = cam.pitch_xy, cam.centre_px
    return y * cam.focal / pitch_y + cy - 0.5, x * cam.focal / pitch_x + cx - 0.5


def dent_sampling(
    scene: Scene, dent: Dent
) -> tuple[str, tuple[float, float] | None, str, tuple[float, float]]:
    """``(unit, (along x, along y), note, (row, col))``: how far the screen point moves per
    camera pixel at the dent's image point, ``|d(u, v)/d(col)|`` and ``|d(u, v)/d(row)|``
    by differences of the neighbouring pixels' screen points; in screen pixels where the
    screen shows fringes on pixels (``emitter.pixel_pitch`` > 0), else in mm. None where
    the dent is not in the image or a neighbour misses the screen (``note`` says which;
    empty where there is a number)."""
    em = scene.emitter
    pitch = float(getattr(em, "pixel_pitch", 0.0) or 0.0)
    shows_pixels = any(p.path == "emitter.pixel_pitch" for p in scene.active.emitter.params)
    pixels = shows_pixels and pitch > 0.0
    unit = SCREEN_PIXELS if pixels else SCREEN_MM
    row, col = image_point(scene, dent.point)
    cam = scene.camera
    i, j = round(row) if math.isfinite(row) else -1, round(col) if math.isfinite(col) else -1
    if not (0 <= i < cam.height and 0 <= j < cam.width):
        return unit, None, "the dent is outside the image", (row, col)
    i0, i1 = max(i - 1, 0), min(i + 1, cam.height - 1)
    j0, j1 = max(j - 1, 0), min(j + 1, cam.width - 1)
    if i0 == i1 or j0 == j1:
        return unit, None, "the image is one pixel wide or high", (row, col)
    traced = trace_pixels(scene, slice(i0, i1 + 1), slice(j0, j1 + 1))
    ci, cj = i - i0, j - j0
    ends = ((ci, 0), (ci, j1 - j0), (0, cj), (i1 - i0, cj))
    if not all(traced.on_screen[end] for end in ends):
        return unit, None, "a pixel next to the dent's misses the screen", (row, col)
    uv = traced.uv
    along_x = float(np.linalg.norm(uv[ci, j1 - j0] - uv[ci, 0])) / (j1 - j0)
    along_y = float(np.linalg.norm(uv[i1 - i0, cj] - uv[0, cj])) / (i1 - i0)
    scale = pitch if pixels else 1.0
    return unit, (along_x / scale, along_y / scale), "", (row, col)
