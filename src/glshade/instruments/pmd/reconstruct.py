"""From decoded screen points to the part: each pixel's point on the nominal surface,
the slope map against the nominal normals, and the heights integrated on a regular grid
around the dent with the Gaussian fitted to them."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from glshade.errors import GlshadeError
from glshade.frame import Region
from glshade.instruments.pmd import decode as pmd
from glshade.instruments.pmd.model import StationModel, aimed_points
from glshade.instruments.pmd.settings import PmdSettings

if TYPE_CHECKING:
    from glshade.rendering import Renderer


# --------------------------------------------------------------------------- geometry
@dataclass(frozen=True)
class Nominal:
    """What the station knows of each pixel: ``points`` (H, W, 3) where its chief ray
    meets the nominal surface (the part without the defect; NaN where it meets none),
    ``normals`` (H, W, 3) the nominal unit normals there, ``camera`` the principal point."""

    points: np.ndarray
    normals: np.ndarray
    camera: np.ndarray


def nominal_geometry(renderer: Renderer, model: StationModel) -> Nominal:
    """Each pixel's point on the model's nominal part along its chief (pinhole) ray, and
    the surface's unit normal there (the surface component's float64 oracle): the
    believed camera's rays onto the believed part (the station's CAD model)."""
    chief = model.part.updated(camera={"f_number": 0.0}, render={"supersample": 1})
    distance = renderer.render(chief, ("distance",)).output("distance").astype(np.float64)
    origin, directions = chief.active.camera.pixel_rays(chief)
    points = np.asarray(origin) + distance[..., None] * directions
    surface = chief.active.surface
    flat = np.zeros(distance.shape)
    normals = np.asarray(
        surface.normal(chief, points[..., 0], points[..., 2], flat, flat), np.float64
    )
    normals = normals / np.linalg.norm(normals, axis=-1, keepdims=True)
    normals[~np.isfinite(distance)] = np.nan
    return Nominal(points, normals, np.asarray(origin, np.float64))


def slope_map(
    model: StationModel, nominal: Nominal, decoded_uv: np.ndarray, region: Region | None = None
) -> np.ndarray:
    """The measured slope deviation ``(∂d/∂x, ∂d/∂z)`` (H, W, 2), rad: the normal that
    bisects the directions to the camera and to the decoded screen point (where the
    station believes it: its screen's plane and sag, and through its believed cover glass
    the point the ray leaves towards, :func:`~glshade.instruments.pmd.model.aimed_points`),
    against the nominal normal. A sequence coding one direction leaves the other
    coordinate at the nominal surface's (the exact map of the defect-free scene is not
    known to a station: the missing coordinate is taken from the nominal mirror, so only
    one slope is measured). ``region``: only its pixels (NaN elsewhere)."""
    cut = (region or Region(0, 0, *decoded_uv.shape[:2])).slices
    points, normals = nominal.points[cut], nominal.normals[cut]
    measured = pmd.normals_from_points(
        points, nominal.camera, aimed_points(model, points, decoded_uv[cut])
    )
    gx, gz = pmd.slope_deviation(measured, normals)
    slopes = np.full((*decoded_uv.shape[:2], 2), np.nan)
    slopes[cut] = np.stack([gx, gz], axis=-1)
    return slopes


# --------------------------------------------------------------------------- heights
@dataclass(frozen=True)
class HeightGrid:
    """The regular ``(x, z)`` grid the slopes are integrated on: centre, spacing (mm),
    shape (rows along z, columns along x)."""

    x: np.ndarray
    z: np.ndarray

    @property
    def spacing(self) -> tuple[float, float]:
        return float(self.x[1] - self.x[0]), float(self.z[1] - self.z[0])


def height_grid(model: StationModel, nominal: Nominal, settings: PmdSettings) -> HeightGrid:
    """A square grid over the dent's centre ± ``window_sigmas`` of its largest σ, at the
    pixels' own spacing on the surface (their median), at most ``grid_points`` across."""
    defect = model.defect
    cov = np.array([[defect.sigma_x2, defect.sigma_xz], [defect.sigma_xz, defect.sigma_z2]])
    half = settings.window_sigmas * math.sqrt(float(np.linalg.eigvalsh(cov).max()))
    p = nominal.points
    steps = [
        np.abs(np.diff(p[..., 0], axis=1)),
        np.abs(np.diff(p[..., 2], axis=0)),
    ]
    found = [float(np.nanmedian(s)) for s in steps if np.isfinite(s).any()]
    pitch = min(found) if found else 2.0 * half / settings.grid_points
    count = int(min(settings.grid_points, max(16, math.ceil(2.0 * half / pitch) + 1)))
    x = defect.x0 + np.linspace(-half, half, count)
    z = defect.z0 + np.linspace(-half, half, count)
    return HeightGrid(x, z)


def project(model: StationModel, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Image ``(rows, cols)`` (pixel units, centres at integers) of world points (…, 3)
    through the model's camera, its distortion included; NaN behind the camera."""
    from glshade.components.camera.perspective.optics import distort

    cam, pose = model.camera, model.pose
    d = np.asarray(points, np.float64) - pose.position
    depth = d @ pose.forward
    with np.errstate(invalid="ignore", divide="ignore"):
        x = np.where(depth > 0, (d @ pose.right) / depth, np.nan)
        y = np.where(depth > 0, -(d @ pose.up) / depth, np.nan)
    if any(cam.distortion):
        x, y = distort(cam.distortion, x, y)
    (pitch_x, pitch_y), (cx, cy) = cam.pitch_xy, cam.centre_px
    cols = x * cam.focal / pitch_x + cx - 0.5
    rows = y * cam.focal / pitch_y + cy - 0.5
    return rows, cols


def sample(image: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Bilinear samples of ``image`` at fractional ``(rows, cols)``; NaN outside, or where
    a neighbour is NaN."""
    from scipy.ndimage import map_coordinates

    height, width = image.shape
    inside = (rows >= 0) & (rows <= height - 1) & (cols >= 0) & (cols <= width - 1)
    values = np.full(rows.shape, np.nan)
    if not inside.any():
        return values
    coords = np.stack([rows[inside], cols[inside]])
    finite = np.isfinite(image)
    filled = np.where(finite, image, 0.0)
    values[inside] = map_coordinates(filled, coords, order=1, mode="nearest")
    weight = map_coordinates(finite.astype(np.float64), coords, order=1, mode="nearest")
    values[inside] = np.where(weight > 1.0 - 1e-9, values[inside], np.nan)
    return values


def fitted_dent(height_um: np.ndarray, x: np.ndarray, z: np.ndarray) -> pmd.Dent | None:
    """The Gaussian fitted to the heights, or None where the fit fails or lands where no
    dent of these heights can be: a depth beyond twice the heights' range, or a σ or a
    centre beyond the grid."""
    finite = height_um[np.isfinite(height_um)]
    if finite.size < 5:
        return None
    try:
        dent = pmd.dent_from_height(height_um, x, z)
    except (GlshadeError, RuntimeError, ValueError):
        return None
    span = float(finite.max() - finite.min())
    reach = max(float(np.ptp(x)), float(np.ptp(z)))
    plausible = (
        math.isfinite(dent.depth)
        and abs(dent.depth) <= 2.0 * span
        and 0.0 < dent.sigma_mm <= reach
        and float(np.min(x)) <= dent.x0_mm <= float(np.max(x))
        and float(np.min(z)) <= dent.z0_mm <= float(np.max(z))
    )
    return dent if plausible else None


@dataclass(frozen=True)
class Heights:
    """The reconstructed defect: ``grid`` and its heights (µm, rows along z), the fitted
    Gaussian (``dent``, None where the fit failed) and the heights at each pixel (µm)."""

    grid: HeightGrid
    height_um: np.ndarray
    dent: pmd.Dent | None
    per_pixel_um: np.ndarray


def reconstruct(
    model: StationModel,
    nominal: Nominal,
    slopes: np.ndarray,
    settings: PmdSettings,
    region: Region | None = None,
) -> Heights:
    """Slopes → heights on the grid → the dent: the slope map sampled at the grid's points
    (projected through the camera onto the image), integrated by least squares (tilt and
    offset removed beyond ``plane_sigmas``), and the Gaussian fitted to it; the heights
    at each pixel of ``region`` (default: the image; NaN elsewhere)."""
    from scipy.interpolate import RegularGridInterpolator

    grid = height_grid(model, nominal, settings)
    xx, zz = np.meshgrid(grid.x, grid.z)
    part = model.part
    yy = np.asarray(part.active.surface.height(part, xx, zz), np.float64)
    rows, cols = project(model, np.stack([xx, yy, zz], axis=-1))
    gx = sample(slopes[..., 0], rows, cols)
    gz = sample(slopes[..., 1], rows, cols)
    defect = model.defect
    cov = np.array([[defect.sigma_x2, defect.sigma_xz], [defect.sigma_xz, defect.sigma_z2]])
    rel = np.stack([xx - defect.x0, zz - defect.z0], axis=-1)
    mahalanobis = np.sqrt(np.einsum("...i,ij,...j->...", rel, np.linalg.inv(cov), rel))
    outside = mahalanobis > settings.plane_sigmas
    valid = np.isfinite(gx) & np.isfinite(gz)
    if settings.heights == "frankot-chellappa" and not valid.all():
        raise GlshadeError(
            "heights = frankot-chellappa needs every grid point seen and valid; "
            f"{int((~valid).sum())} of {valid.size} are not (use least-squares)"
        )
    height_mm = pmd.integrate_slopes(
        gx, gz, grid.spacing, valid=valid, outside=outside, method=settings.heights
    )
    height_um = 1e3 * height_mm
    dent = fitted_dent(height_um, xx, zz)
    lookup = RegularGridInterpolator(
        (grid.z, grid.x), height_um, bounds_error=False, fill_value=np.nan
    )
    cut = (region or Region(0, 0, *slopes.shape[:2])).slices
    p = nominal.points[cut]
    per_pixel = np.full(slopes.shape[:2], np.nan, np.float32)
    per_pixel[cut] = lookup(np.stack([p[..., 2], p[..., 0]], axis=-1))
    return Heights(grid, height_um, dent, per_pixel)
