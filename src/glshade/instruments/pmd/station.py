"""Phase-measuring deflectometry, measured: what a PMD station would measure of a scene's
dent (docs/pmd.md).

A case renders the fringe sequence of the scene and of its defect-free twin through the
whole imaging chain (one trace each: every ray is shaded for every frame,
:meth:`Renderer.render <glshade.gpu.renderer.Renderer.render>` with the ``frames``
output), records each frame with the sensor's own noise, decodes both like a station
(:mod:`glshade.instruments.pmd.decode`), and compares:

- the decoded screen points with and without the dent (``pmd_shift_mm``), against the
  noise of two decodes of the defect-free scene with different seeds (``pmd_noise_mm``)
  and its prediction from the modulation;
- the decoded points against the exact map the renderer traced (``decode_rms_mm``,
  ``unwrap_failures``);
- the measured normals (each pixel's point taken on the nominal surface, as a station
  takes it on the part's CAD model) against the nominal ones: the slope map, integrated
  on a regular ``(x, z)`` grid around the dent into heights, and the Gaussian fitted to
  them (``pmd_depth_um``).

The defect-free analysis (:class:`PmdBaseline`) is shared by every dent on one geometry,
as the paper metric's :class:`~glshade.metrics.visibility.Baseline` is.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from glshade.components.base import no_sequence
from glshade.components.emitter.fringes.table import (
    DIRECTIONS,
    FringeFrame,
    FringesTable,
    fringes_of,
)
from glshade.errors import GlshadeError, SceneError
from glshade.instruments.pmd import decode as pmd
from glshade.metrics.coding_laws import white_fundamental
from glshade.metrics.status import (
    STATUSES,
    Status,
    combined,
    coverage_edge,
    dent_window,
    no_dent,
    touches_edge,
)
from glshade.oracle.lobe import finish_share
from glshade.params import Table, param
from glshade.scene import Scene

if TYPE_CHECKING:
    from glshade.rendering import Renderer

#: The share of its largest move above which a pixel belongs to the dent's region.
REGION_SHARE = 0.2
#: Where the finish's lobe keeps less than this share of the finest fringe (its closed
#: form), an unresolved case names the finish as the cause.
FINISH_CAUSE_SHARE = 0.5
#: The share of the dent's seen region that may be invalid (modulation too low) before
#: its numbers cannot be read.
INVALID_SHARE = 0.25
#: The version of what a PMD case measures: part of a PMD sweep case's identity and of its
#: manifest. Raise it with any change that alters a number of a PMD record.
PMD_VERSION = 2


@dataclass(frozen=True)
class PmdSettings(Table):
    """How a PMD case is decoded and reconstructed.

    ``modulation_share``: a pixel is valid where every period's modulation is at least
    this share of ``amplitude`` times the image's response to the screen's white (its
    brightest pixel); ``min_modulation`` (recorded units) replaces that threshold when
    given. ``heights``: ``least-squares`` or ``frankot-chellappa`` (a rectangle of valid
    grid points only). ``grid_points``: the height grid's samples along its longer side;
    ``window_sigmas``: the grid spans the dent's centre ± this many σ (its largest);
    ``plane_sigmas``: tilt and offset are fitted where the Mahalanobis distance to the
    dent exceeds this."""

    table = "measure"

    modulation_share: float = param(
        "measure.modulation_share", "", 0.1,
        "pmd: a pixel is valid where every period's modulation is at least this share of "
        "the amplitude times the response to the screen's white",
        lo=0.0, hi=1.0, flag="--modulation-share",
    )  # fmt: skip
    min_modulation: float | None = param(
        "measure.min_modulation", "", None,
        "pmd: the least modulation (recorded units) of a valid pixel, instead of "
        "modulation_share (unset: modulation_share decides)",
        lo=0.0,
    )  # fmt: skip
    heights: str = param(
        "measure.heights", "", "least-squares",
        "pmd: how heights are integrated from the slopes (frankot-chellappa: a rectangle of "
        "valid grid points only)",
        value_type="choice", choices=("least-squares", "frankot-chellappa"), flag="--heights",
    )  # fmt: skip
    grid_points: int = param(
        "measure.grid_points", "", 160, "pmd: the height grid's samples along its longer side",
        value_type="integer", lo=16, hi=1024,
    )  # fmt: skip
    window_sigmas: float = param(
        "measure.window_sigmas", "", 5.0,
        "pmd: the height grid spans the dent's centre ± this many σ (its largest)",
        lo=0.0, hi=20.0, closed=True, nonzero=True, allowed_text="in (0, 20]",
    )  # fmt: skip
    plane_sigmas: float = param(
        "measure.plane_sigmas", "", 3.5,
        "pmd: tilt and offset are fitted where the Mahalanobis distance to the dent exceeds "
        "this (below window_sigmas)",
        lo=0.0, hi=20.0,
    )  # fmt: skip

    @staticmethod
    def _sigmas(values: dict[str, Any]) -> None:
        if not values["plane_sigmas"] < values["window_sigmas"]:
            raise SceneError(
                "measure.plane_sigmas",
                f"below measure.window_sigmas ({values['window_sigmas']:g})",
                values["plane_sigmas"],
            )

    table_checks = (_sigmas,)


def check_scene(scene: Scene) -> None:
    """Refuse, in one line, a scene a PMD station cannot decode: another emitter than the
    fringes, or a coding that cannot be decoded (an amplitude of 0 or above the offset:
    :meth:`~glshade.components.emitter.fringes.codec.FringeCodec.check_decodable`)."""
    if scene.active.emitter.measured_by != "pmd":
        raise GlshadeError(no_sequence(scene.emitter.kind))
    fringes_of(scene).codec.check_decodable()


# --------------------------------------------------------------------------- capture
@dataclass(frozen=True)
class Capture:
    """One scene's fringe sequence, shaded in one trace: ``radiance`` (F, H, W) of the
    coded ``frames`` in order, ``white`` (H, W) the response to the screen's full scale,
    ``uv`` (H, W, 2) the exact screen points (mm, NaN where none), ``gain`` the exposure
    (recorded units per radiance; 1 without a sensor)."""

    scene: Scene
    frames: tuple[FringeFrame, ...]
    radiance: np.ndarray
    white: np.ndarray
    uv: np.ndarray
    gain: float
    seconds: float

    def recorded(self, seed_offset: int = 0) -> np.ndarray:
        """The sequence as the sensor records it (float32, F × H × W; the radiance itself
        without a sensor): each frame with its own noise, drawn from the sensor's seed
        (plus ``seed_offset``), the scene and the frame shown; the sensor's black level
        kept, as a camera's raw frames keep it."""
        if not self.scene.active.records(self.scene):
            return self.radiance
        out = np.empty_like(self.radiance)
        for index, frame in enumerate(self.frames):
            out[index] = self._developed(frame, self.radiance[index], seed_offset)
        return out

    def recorded_white(self, seed_offset: int = 0) -> np.ndarray:
        """The screen's white as the sensor records it (H × W, exposed as the sequence,
        with its own noise; the radiance without a sensor)."""
        if not self.scene.active.records(self.scene):
            return self.white
        white = self.scene.active.emitter.white(self.scene)
        return self._developed(white, self.white, seed_offset)

    def _developed(self, frame: FringeFrame, radiance: np.ndarray, seed_offset: int) -> np.ndarray:
        scene = self.scene
        base = scene.with_value("camera.exposure", self.gain)
        if seed_offset:
            base = base.with_value("sensor.seed", (scene.sensor.seed + seed_offset) % 2**63)
        shown = scene.active.emitter.showing(base, frame)
        return shown.active.develop(shown, radiance.copy())

    @property
    def black_level(self) -> float:
        """The sensor's black level in recorded units (0 without a sensor): what every
        recorded value holds on top of its signal."""
        records = self.scene.active.records(self.scene)
        return self.scene.sensor.black_level if records else 0.0

    @property
    def peak_response(self) -> float:
        """The noise-free recorded response of the brightest pixel to the screen's white,
        above the black level (recorded units; the radiance without a sensor): the base
        of the validity threshold. The full well fills the range above the black level,
        so a response ``gain · W`` is ``(1 - black) · min(gain · W, 1)`` of full scale."""
        white = self.white[np.isfinite(self.white)]
        peak = float(white.max()) * self.gain if white.size else 0.0
        if not self.scene.active.records(self.scene):
            return peak
        return (1.0 - self.black_level) * min(peak, 1.0)


def released(shot: Capture) -> Capture:
    """``shot`` without its frames (an empty ``(0, H, W)`` stack): what a baseline keeps
    once it has decoded them (its white frame, exact map and gain), so a dent measured
    against it holds one sequence, its own, not two."""
    # the white frame is a layer of the rendered stack: copied, it no longer holds the stack
    return dataclasses.replace(shot, radiance=shot.radiance[:0].copy(), white=shot.white.copy())


def capture(renderer: Renderer, scene: Scene) -> Capture:
    """Render ``scene``'s whole coded sequence and its white frame in one trace."""
    start = time.perf_counter()
    emitter = scene.active.emitter
    frames = tuple(emitter.sequence(scene))
    stack = renderer.render(scene, ("frames", "uv"), frames=(*frames, emitter.white(scene)))
    layers = stack.output("frames")
    gain = renderer.exposure_gain(scene) if scene.active.records(scene) else 1.0
    return Capture(
        scene,
        frames,
        layers[:-1],
        layers[-1],
        stack.output("uv").astype(np.float64),
        gain,
        time.perf_counter() - start,
    )


# --------------------------------------------------------------------------- decoding
@dataclass(frozen=True)
class Decoding:
    """A recorded sequence decoded: ``uv`` (H, W, 2) the decoded screen points in mm (NaN
    where a direction is not coded or not valid), ``valid`` (H, W) valid in every coded
    direction, per screen coordinate ``modulation``, ``offset`` and ``wrapped`` (2, K, H,
    W: the first axis in the screen's order (u, v) like ``uv``'s last, whatever order the
    sequence shows them in; NaN for a coordinate the sequence does not code and, where
    ``seen`` was given, for a pixel that sees no screen), ``threshold`` the modulation a
    valid pixel needs (recorded units)."""

    uv: np.ndarray
    valid: np.ndarray
    modulation: np.ndarray
    offset: np.ndarray
    wrapped: np.ndarray
    threshold: float


def threshold_of(scene: Scene, peak_response: float, settings: PmdSettings) -> float:
    """The modulation a valid pixel needs (recorded units): ``min_modulation`` where
    given, else ``modulation_share`` of ``amplitude`` times ``peak_response`` (the
    brightest pixel's response to the screen's white above the black level)."""
    if settings.min_modulation is not None:
        return float(settings.min_modulation)
    return float(settings.modulation_share * fringes_of(scene).amplitude * peak_response)


def decode_sequence(
    scene: Scene,
    recorded: np.ndarray,
    peak_response: float,
    settings: PmdSettings,
    seen: np.ndarray | None = None,
) -> Decoding:
    """Decode every coded direction of a recorded ``(F, H, W)`` sequence (``seen``: the
    pixels that see the screen; the per-direction maps are NaN elsewhere)."""
    em = fringes_of(scene)
    periods, shifts = len(em.periods), em.shifts
    height, width = recorded.shape[1:]
    uv = np.full((height, width, 2), np.nan)
    valid = np.ones((height, width), bool)
    threshold = threshold_of(scene, peak_response, settings)
    # float32 as each direction is decoded: one direction's float64 maps at a time
    shape = (2, periods, height, width)
    modulation, offset, wrapped = (np.full(shape, np.nan, np.float32) for _ in range(3))
    for d, direction in enumerate(em.directions):
        block = recorded[d * periods * shifts : (d + 1) * periods * shifts]
        decoded = pmd.decode(
            block.reshape(periods, shifts, height, width),
            em.codec,
            min_modulation=threshold,
            direction=direction,
        )
        axis = DIRECTIONS.index(direction) ^ 1
        uv[..., axis] = decoded.s_mm - em.half_size[axis]
        valid &= decoded.valid
        modulation[axis], offset[axis], wrapped[axis] = (
            decoded.modulation,
            decoded.offset,
            decoded.wrapped,
        )
        del decoded
    uv[~valid] = np.nan
    if seen is not None:
        for per_direction in (modulation, offset, wrapped):
            per_direction[:, :, ~seen] = np.nan
    return Decoding(uv, valid, modulation, offset, wrapped, threshold)


def seen_pixels(exact_uv: np.ndarray) -> np.ndarray:
    """The pixels whose rays reach the screen (a finite exact screen point)."""
    return np.all(np.isfinite(exact_uv), axis=-1)


def coded_axes(scene: Scene) -> list[int]:
    """The screen coordinates the sequence codes (0: u, 1: v)."""
    return [DIRECTIONS.index(d) ^ 1 for d in fringes_of(scene).directions]


def failures(decoded_uv: np.ndarray, exact_uv: np.ndarray, scene: Scene) -> np.ndarray:
    """Valid pixels where some coded direction decodes more than half the finest period
    away from the exact map (the unwrapping picked another fringe)."""
    half = 0.5 * fringes_of(scene).periods[0]
    bad = np.zeros(decoded_uv.shape[:2], bool)
    for axis in coded_axes(scene):
        with np.errstate(invalid="ignore"):
            bad |= np.abs(decoded_uv[..., axis] - exact_uv[..., axis]) > half
    return bad


# --------------------------------------------------------------------------- geometry
@dataclass(frozen=True)
class Nominal:
    """What the station knows of each pixel: ``points`` (H, W, 3) where its chief ray
    meets the nominal surface (the part without the defect; NaN where it meets none),
    ``normals`` (H, W, 3) the nominal unit normals there, ``camera`` the principal point."""

    points: np.ndarray
    normals: np.ndarray
    camera: np.ndarray


def nominal_geometry(renderer: Renderer, scene: Scene) -> Nominal:
    """Each pixel's point on the nominal surface along its chief (pinhole) ray, and the
    surface's unit normal there (the surface component's float64 oracle)."""
    chief = scene.without_defect().updated(camera={"f_number": 0.0}, render={"supersample": 1})
    distance = renderer.render(chief, ("distance",)).output("distance").astype(np.float64)
    origin, directions = scene.active.camera.pixel_rays(chief)
    points = np.asarray(origin) + distance[..., None] * directions
    surface = scene.active.surface
    flat = np.zeros(distance.shape)
    normals = np.asarray(
        surface.normal(chief, points[..., 0], points[..., 2], flat, flat), np.float64
    )
    normals = normals / np.linalg.norm(normals, axis=-1, keepdims=True)
    normals[~np.isfinite(distance)] = np.nan
    return Nominal(points, normals, np.asarray(origin, np.float64))


def screen_points(scene: Scene, uv: np.ndarray) -> np.ndarray:
    """World points (mm) of screen coordinates ``uv`` (…, 2)."""
    plane = scene.emitter_plane()
    return plane.centre + uv[..., :1] * plane.e_u + uv[..., 1:] * plane.e_v


def slope_map(scene: Scene, nominal: Nominal, decoded_uv: np.ndarray) -> np.ndarray:
    """The measured slope deviation ``(∂d/∂x, ∂d/∂z)`` (H, W, 2), rad: the normal that
    bisects the directions to the camera and to the decoded screen point, against the
    nominal normal. A sequence coding one direction leaves the other coordinate at the
    nominal surface's (the exact map of the defect-free scene is not known to a station:
    the missing coordinate is taken from the nominal mirror, so only one slope is
    measured)."""
    measured = pmd.normals_from_points(
        nominal.points, nominal.camera, screen_points(scene, decoded_uv)
    )
    gx, gz = pmd.slope_deviation(measured, nominal.normals)
    return np.stack([gx, gz], axis=-1)


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


def height_grid(scene: Scene, nominal: Nominal, settings: PmdSettings) -> HeightGrid:
    """A square grid over the dent's centre ± ``window_sigmas`` of its largest σ, at the
    pixels' own spacing on the surface (their median), at most ``grid_points`` across."""
    defect = scene.defect
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


def project(scene: Scene, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Image ``(rows, cols)`` (pixel units, centres at integers) of world points (…, 3)
    through the camera, its distortion included; NaN behind the camera."""
    from glshade.components.camera.perspective.optics import distort

    cam = scene.camera
    pose = cam.pose()
    d = np.asarray(points, np.float64) - pose.position
    depth = d @ pose.forward
    with np.errstate(invalid="ignore", divide="ignore"):
        x = np.where(depth > 0, (d @ pose.right) / depth, np.nan)
        y = np.where(depth > 0, -(d @ pose.up) / depth, np.nan)
    if any(cam.distortion):
        x, y = distort(cam.distortion, x, y)
    cols = x * cam.focal / cam.pixel_pitch + cam.width / 2.0 - 0.5
    rows = y * cam.focal / cam.pixel_pitch + cam.height / 2.0 - 0.5
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
    scene: Scene, nominal: Nominal, slopes: np.ndarray, settings: PmdSettings
) -> Heights:
    """Slopes → heights on the grid → the dent: the slope map sampled at the grid's points
    (projected through the camera onto the image), integrated by least squares (tilt and
    offset removed beyond ``plane_sigmas``), and the Gaussian fitted to it."""
    from scipy.interpolate import RegularGridInterpolator

    grid = height_grid(scene, nominal, settings)
    xx, zz = np.meshgrid(grid.x, grid.z)
    yy = np.asarray(scene.active.surface.height(scene, xx, zz), np.float64)
    rows, cols = project(scene, np.stack([xx, yy, zz], axis=-1))
    gx = sample(slopes[..., 0], rows, cols)
    gz = sample(slopes[..., 1], rows, cols)
    defect = scene.defect
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
    p = nominal.points
    per_pixel = lookup(np.stack([p[..., 2], p[..., 0]], axis=-1)).astype(np.float32)
    return Heights(grid, height_um, dent, per_pixel)


# --------------------------------------------------------------------------- baseline
@dataclass
class PmdBaseline:
    """The defect-free analysis of one geometry, shared by every dent on it: its capture,
    decoded from one recording and again from a second with another seed (the noise),
    the nominal geometry, and the prediction of the noise."""

    scene: Scene
    settings: PmdSettings
    capture: Capture
    decoding: Decoding
    twin: Decoding | None
    nominal: Nominal
    seconds: dict[str, float] = field(default_factory=dict)

    def noise_pixels(self, window: np.ndarray) -> np.ndarray:
        """The pixels of ``window`` the noise is measured on: valid in both noisy decodes,
        and decoded by neither on another fringe than the exact map's (an unwrapping
        failure is counted, not taken for noise). None are without a sensor."""
        if self.twin is None:
            return np.zeros(window.shape, bool)
        exact = self.capture.uv
        # off the edge of the valid region too (:func:`interior`), as the dent's shift
        both = window & interior(self.decoding.valid & self.twin.valid)
        both &= ~failures(self.decoding.uv, exact, self.scene)
        return both & ~failures(self.twin.uv, exact, self.scene)

    def noise(self, window: np.ndarray) -> Noise:
        """The decoded coordinate's noise over the pixels of ``window``
        (:meth:`noise_pixels`), each coded coordinate counted: the standard deviation of
        the two noisy decodes' differences over sqrt 2, the largest difference, and the
        prediction from the modulation (all 0 without a sensor)."""
        if self.twin is None:
            return Noise(0.0, 0.0, 0.0)
        pixels = self.noise_pixels(window)
        diff = (self.decoding.uv - self.twin.uv)[pixels][:, coded_axes(self.scene)]
        if not diff.size:
            return Noise(math.nan, math.nan, math.nan)
        return Noise(
            float(np.std(diff) / math.sqrt(2.0)),
            float(np.abs(diff).max()),
            predicted_noise_mm(self.scene, self.decoding, pixels),
        )


@dataclass(frozen=True)
class Noise:
    """The decoded coordinate's noise (mm): ``std``, ``floor`` (the largest shift noise
    alone makes) and ``predicted`` (:func:`predicted_noise_mm`)."""

    std: float
    floor: float
    predicted: float


def pmd_baseline(
    renderer: Renderer, scene: Scene, settings: PmdSettings = PmdSettings()
) -> PmdBaseline:
    """The defect-free analysis of ``scene``'s geometry (its defect is ignored)."""
    check_scene(scene)
    normal = scene.without_defect()
    shot = capture(renderer, normal)
    start = time.perf_counter()
    seen = seen_pixels(shot.uv)
    decoding = decode_sequence(normal, shot.recorded(), shot.peak_response, settings, seen)
    twin = None
    if normal.active.records(normal):
        twice = shot.recorded(seed_offset=1)
        twin = decode_sequence(normal, twice, shot.peak_response, settings, seen)
    decode_s = time.perf_counter() - start
    nominal = nominal_geometry(renderer, scene)
    return PmdBaseline(
        normal,
        settings,
        released(shot),
        decoding,
        twin,
        nominal,
        {"render": shot.seconds, "decode": decode_s},
    )


# --------------------------------------------------------------------------- noise
def predicted_noise_mm(scene: Scene, decoding: Decoding, mask: np.ndarray) -> float:
    """``periods[0] / 2π · sqrt(2 / N) · σ_I / B`` per pixel of ``mask`` (valid ones),
    pooled as the root mean square (what the measured standard deviation estimates):
    ``σ_I`` the sensor's noise at the pixel's mean level ``A`` (recorded units, the black
    level ``b`` in it: the signal ``A - b`` fills ``1 - b`` of full scale at the full well,
    so photon noise ``(1 - b) (A - b) / full_well`` and read noise ``((1 - b) read /
    full_well)²`` in variance, and the quantisation's ``q² / 12``), ``B`` its modulation
    of the finest period, each coded direction counted. 0 without a sensor."""
    sensor, em = scene.sensor, fringes_of(scene)
    if sensor.full_well_e is None:
        return 0.0
    full_well, black = sensor.full_well_e, sensor.black_level
    q = 1.0 / sensor.full_scale_dn
    scale = em.periods[0] / (2.0 * math.pi)
    variances = []
    for axis in coded_axes(scene):
        level = decoding.offset[axis, 0][mask].astype(np.float64)
        modulation = decoding.modulation[axis, 0][mask].astype(np.float64)
        sigma2 = (
            (1.0 - black) * np.maximum(level - black, 0.0) / full_well
            + ((1.0 - black) * sensor.read_noise_e / full_well) ** 2
            + q * q / 12.0
        )
        variances.append(scale**2 * (2.0 / em.shifts) * sigma2 / modulation**2)
    pooled = np.concatenate(variances)
    return float(math.sqrt(pooled.mean())) if pooled.size else math.nan


# --------------------------------------------------------------------------- modulation
def modulation_share(scene: Scene, shot: Capture) -> np.ndarray:
    """Per screen coordinate (u, v) and pixel (2, H, W, float32), the finest period's
    modulation share of the noise-free radiance, ``B / (b_1 W)``: ``B`` the pixel's
    modulation of the finest fringes, ``W`` its own response to the screen's white, and
    ``b_1`` the fundamental of the fringe the screen displays over the white it displays
    (:func:`displayed_fundamental`). What the finish, the lens and the pixel's footprint
    leave of the fringe: 1 for a sharp mirror (within the screen's grey levels' rounding,
    ±0.5 % at 256 levels), less where they average it out; an optical property, before
    the sensor. NaN for a coordinate not coded and for a pixel that sees no screen."""
    em = fringes_of(scene)
    fundamental = displayed_fundamental(em)
    white = shot.white.astype(np.float64)
    seen = seen_pixels(shot.uv) & np.isfinite(white) & (white > 0.0)
    share = np.full((2, *white.shape), np.nan, np.float32)
    steps = em.codec.shifts_rad
    for d, direction in enumerate(em.directions):
        first = d * len(em.periods) * em.shifts
        finest = shot.radiance[first : first + em.shifts].astype(np.float64)
        sine = np.tensordot(np.sin(steps), finest, axes=1)
        cosine = np.tensordot(np.cos(steps), finest, axes=1)
        modulation = (2.0 / em.shifts) * np.hypot(sine, cosine)
        with np.errstate(invalid="ignore", divide="ignore"):
            ratio = modulation / (fundamental * white)
        share[DIRECTIONS.index(direction) ^ 1] = np.where(seen, ratio, np.nan)
    return share


def displayed_fundamental(em: FringesTable) -> float:
    """``b_1`` of the fringe the screen displays, ``displayed(offset + amplitude cos θ)``
    (its grey levels, response, black level and ambient light included), over the white
    it displays, ``displayed(1)``: a sharp mirror's modulation per unit of its response to
    the white (:func:`~glshade.metrics.coding_laws.white_fundamental`)."""
    return white_fundamental(em)


def median_share(scene: Scene, share: np.ndarray, region: np.ndarray) -> float:
    """The record's ``modulation``: the median of :func:`modulation_share` over the coded
    coordinates of the dent's region, else (no region) of every pixel that sees the
    screen; NaN where none does."""
    values = share[coded_axes(scene)].astype(np.float64)
    where = region if region.any() else np.isfinite(values).all(axis=0)
    picked = values[:, where]
    picked = picked[np.isfinite(picked)]
    return float(np.median(picked)) if picked.size else math.nan


# --------------------------------------------------------------------------- one case
@dataclass(frozen=True)
class PmdResult:
    """What a PMD station measures of one scene's dent (lengths on the screen in mm,
    slopes in µrad, heights in µm) with its status, the maps behind the numbers and the
    seconds spent."""

    pmd_shift_mm: float
    pmd_shift_exact_mm: float
    pmd_noise_mm: float
    pmd_noise_floor_mm: float
    pmd_noise_predicted_mm: float
    pmd_snr: float
    pmd_slope_urad: float
    pmd_depth_um: float
    pmd_sigma_mm: float
    decode_rms_mm: float
    unwrap_failures: int
    valid_fraction: float
    modulation: float
    status: str
    status_reason: str
    maps: PmdMaps
    seconds: dict[str, float]


@dataclass(frozen=True)
class Recording:
    """How a case's frames were recorded, what decoding them takes: ``gain`` the exposure
    applied (``camera.exposure`` as a number, ``"auto"`` worked out: radiance ``1 / gain``
    fills the full well, the range from the black level to full scale; 1 without a
    sensor), ``black_level`` (recorded units, full scale 1; 0 without a sensor),
    ``white_response`` the brightest pixel's noise-free response to the screen's white
    above the black level (the validity threshold's base), ``threshold`` the modulation a
    valid pixel needs (recorded units) and ``modulation_share`` the share of ``amplitude``
    times ``white_response`` it is (None where ``PmdSettings.min_modulation`` set it),
    ``white`` (H, W) the screen's white as recorded."""

    gain: float
    black_level: float
    white_response: float
    threshold: float
    modulation_share: float | None
    white: np.ndarray


@dataclass(frozen=True)
class PmdMaps:
    """The maps of one case, image-aligned (H, W[, 2]) unless said; every per-direction
    axis in the screen's order (u, v), NaN for a coordinate the sequence does not code.

    ``decoded`` the decoded screen points (mm, NaN invalid), ``exact`` the traced ones,
    ``error`` decoded minus exact (mm); the defect-free scene's ``exact_defect_free``,
    ``decoded_defect_free`` and ``decoded_twin`` (its second recording, another seed: the
    noise; without a sensor the same radiance, so the same decode); ``modulation`` and
    ``wrapped`` (2, K, H, W; NaN where no screen is seen), ``modulation_share`` (2, H, W:
    :func:`modulation_share`); ``slopes_urad``, ``height_um`` and the heights' grid;
    ``failed`` (unwrapping failures), ``region`` (the dent's region), ``shift_pixels`` and
    ``noise_pixels`` (the pixels ``pmd_shift_mm`` and ``pmd_noise_mm`` are taken over);
    ``recorded`` the case's recorded sequence (F, H, W, in the order shown) and
    ``recording`` how it was recorded."""

    decoded: np.ndarray
    exact: np.ndarray
    error: np.ndarray
    exact_defect_free: np.ndarray
    decoded_defect_free: np.ndarray
    decoded_twin: np.ndarray
    modulation: np.ndarray
    wrapped: np.ndarray
    modulation_share: np.ndarray
    slopes_urad: np.ndarray
    height_um: np.ndarray
    heights: Heights
    failed: np.ndarray
    region: np.ndarray
    shift_pixels: np.ndarray
    noise_pixels: np.ndarray
    recorded: np.ndarray
    recording: Recording


def interior(seen: np.ndarray) -> np.ndarray:
    """The pixels of ``seen`` whose eight neighbours are in it too. A pixel on the edge of
    what sees the screen straddles it: with several rays a pixel its exact screen point is
    the mean of the rays that reach the screen, and the least move of the screen's edge
    across its footprint (a dent's faint tail) changes which rays those are and jumps the
    mean by a share of the footprint. Its move is not the dent's."""
    from scipy.ndimage import binary_erosion

    return binary_erosion(seen, structure=np.ones((3, 3), bool), border_value=1)


def seen_in_both(exact0: np.ndarray, exact1: np.ndarray, axes: list[int]) -> np.ndarray:
    """Pixels whose every coded coordinate is finite in both exact maps, off their edge
    (:func:`interior`)."""
    seen = np.all(np.isfinite(exact0[..., axes]), axis=-1)
    return interior(seen & np.all(np.isfinite(exact1[..., axes]), axis=-1))


def dent_region(scene: Scene, exact0: np.ndarray, exact1: np.ndarray) -> np.ndarray:
    """Where, inside its window and off the edge of what sees the screen
    (:func:`interior`), the dent moves the exact screen points by at least
    :data:`REGION_SHARE` of its largest move."""
    window = dent_window(scene, exact0.shape[:2])
    axes = coded_axes(scene)
    moved = np.linalg.norm((exact1 - exact0)[..., axes], axis=-1)
    moved = np.where(window & seen_in_both(exact0, exact1, axes), moved, 0.0)
    peak = float(moved.max()) if moved.size else 0.0
    if peak <= 0.0:
        return np.zeros(moved.shape, bool)
    return moved >= REGION_SHARE * peak


def measure_pmd_scene(
    renderer: Renderer,
    scene: Scene,
    settings: PmdSettings = PmdSettings(),
    baseline: PmdBaseline | None = None,
) -> PmdResult:
    """What a PMD station measures of ``scene``'s dent, on an existing renderer
    (``baseline``: the defect-free analysis of the same geometry, when the caller has
    it; without one, a case whose buffers and analysis would exceed the renderer's memory
    budget is refused first, in one line: :func:`glshade.instruments.memory.check_pmd`)."""
    check_scene(scene)
    if baseline is None:
        from glshade.instruments.memory import check_pmd

        check_pmd(scene, renderer.memory_budget_bytes)
        baseline = pmd_baseline(renderer, scene, settings)
    shot = capture(renderer, scene)
    start = time.perf_counter()
    recorded = shot.recorded()
    peak = baseline.capture.peak_response
    decoding = decode_sequence(scene, recorded, peak, settings, seen_pixels(shot.uv))
    share = settings.modulation_share if settings.min_modulation is None else None
    white = shot.recorded_white()
    recording = Recording(shot.gain, shot.black_level, peak, decoding.threshold, share, white)
    decode_s = time.perf_counter() - start
    start = time.perf_counter()
    slopes = slope_map(scene, baseline.nominal, decoding.uv)
    heights = reconstruct(scene, baseline.nominal, slopes, settings)
    heights_s = time.perf_counter() - start
    seconds = {"render": shot.seconds, "decode": decode_s, "heights": heights_s}
    return _result(scene, baseline, shot, recorded, recording, decoding, slopes, heights, seconds)


def _result(
    scene: Scene,
    baseline: PmdBaseline,
    shot: Capture,
    recorded: np.ndarray,
    recording: Recording,
    decoding: Decoding,
    slopes: np.ndarray,
    heights: Heights,
    seconds: dict[str, float],
) -> PmdResult:
    axes = coded_axes(scene)
    base, exact0 = baseline.decoding, baseline.capture.uv
    window = dent_window(scene, decoding.valid.shape)
    failed = failures(decoding.uv, shot.uv, scene)
    # valid in both decodes and off the edge of that region (a pixel straddling it mixes
    # the screen with the curtain: :func:`interior`)
    both = window & interior(decoding.valid & base.valid)
    both &= ~failed & ~failures(base.uv, exact0, scene)
    shift = np.linalg.norm((decoding.uv - base.uv)[..., axes], axis=-1)
    moved = np.linalg.norm((shot.uv - exact0)[..., axes], axis=-1)
    moved = np.where(window & seen_in_both(exact0, shot.uv, axes), moved, np.nan)
    noise = baseline.noise(window)
    region = dent_region(scene, exact0, shot.uv)
    status = assess_pmd(scene, baseline, shot, decoding, region, failed, _largest(moved), noise)
    shift_mm = _largest(np.where(both, shift, np.nan))
    slope = np.hypot(slopes[..., 0], slopes[..., 1])
    share = modulation_share(scene, shot)
    dent = heights.dent
    return PmdResult(
        pmd_shift_mm=shift_mm,
        pmd_shift_exact_mm=_largest(moved),
        pmd_noise_mm=noise.std,
        pmd_noise_floor_mm=noise.floor,
        pmd_noise_predicted_mm=noise.predicted,
        pmd_snr=shift_mm / noise.std if noise.std > 0 else math.inf,
        pmd_slope_urad=1e6 * _largest(np.where(region & decoding.valid & ~failed, slope, np.nan)),
        pmd_depth_um=dent.depth if dent is not None else math.nan,
        pmd_sigma_mm=dent.sigma_mm if dent is not None else math.nan,
        decode_rms_mm=_decode_rms(scene, baseline),
        unwrap_failures=int(failed.sum()),
        valid_fraction=_valid_share(decoding, shot.uv[..., axes[0]]),
        modulation=median_share(scene, share, region),
        status=status.status,
        status_reason=status.reason,
        maps=PmdMaps(
            decoded=decoding.uv,
            exact=shot.uv,
            error=decoding.uv - shot.uv,
            exact_defect_free=exact0,
            decoded_defect_free=base.uv,
            decoded_twin=base.uv if baseline.twin is None else baseline.twin.uv,
            modulation=decoding.modulation,
            wrapped=decoding.wrapped,
            modulation_share=share,
            slopes_urad=(1e6 * slopes).astype(np.float32),
            height_um=heights.per_pixel_um,
            heights=heights,
            failed=failed,
            region=region,
            shift_pixels=both,
            noise_pixels=baseline.noise_pixels(window),
            recorded=recorded,
            recording=recording,
        ),
        seconds=seconds,
    )


def _largest(values: np.ndarray) -> float:
    """The largest finite value (NaN for none)."""
    finite = values[np.isfinite(values)]
    return float(finite.max()) if finite.size else math.nan


def _decode_rms(scene: Scene, baseline: PmdBaseline) -> float:
    """Root mean square of the defect-free scene's decoded minus exact points over its valid
    pixels that did not fail to unwrap, each coded coordinate counted."""
    base, exact = baseline.decoding, baseline.capture.uv
    ok = base.valid & ~failures(base.uv, exact, scene)
    error = (base.uv - exact)[ok][:, coded_axes(scene)]
    return float(np.sqrt(np.mean(error**2))) if error.size else math.nan


def _valid_share(decoding: Decoding, exact: np.ndarray) -> float:
    """Valid pixels over the pixels that see the screen."""
    seen = np.isfinite(exact)
    return float(decoding.valid[seen].mean()) if seen.any() else 0.0


# --------------------------------------------------------------------------- status
def assess_pmd(
    scene: Scene,
    baseline: PmdBaseline,
    shot: Capture,
    decoding: Decoding,
    region: np.ndarray,
    failed: np.ndarray,
    exact_mm: float,
    noise: Noise,
) -> Status:
    """Whether a PMD case's numbers can be read: ``outside`` (the dent moves no seen
    pixel), ``edge`` (its region touches the image's border or the edge of what sees the
    screen, or a height map's holes or edge), ``unresolved`` (more than
    :data:`INVALID_SHARE` of its region is not valid: the fringes are averaged out),
    ``saturated``/``underexposed`` (the recorded frames), ``noise`` (the shift the dent
    makes, ``exact_mm`` from the traced maps, is not above the largest shift noise alone
    makes, so the decoded shift is noise's; or the unwrapping fails in the dent's
    region). A scene without a dent is ``outside`` whatever else holds
    (:func:`~glshade.metrics.status.no_dent`, as the stripe metric says it)."""
    absent = no_dent(scene)
    if absent is not None:
        return absent
    if not region.any():
        return Status(
            "outside",
            "the dent is not seen: no pixel that sees the screen moves (move the dent, "
            "defect.x0/z0, or the camera)",
        )
    found = [_pmd_edge(scene, region, shot), _pmd_resolution(scene, region, decoding)]
    if scene.active.records(scene):
        found.append(_pmd_exposure(baseline))
    floor = noise.floor
    if baseline.twin is not None and not exact_mm > floor:
        hint = ""
        if noise.std > 2.0 * noise.predicted:
            hint = (
                f" (the noise is {noise.std / noise.predicted:.3g} times its prediction: the "
                f"{fringes_of(scene).periods[0]:g} mm fringes alias or nearly fail to unwrap "
                "there; a longer emitter.periods[0] or a smaller period ratio helps)"
            )
        found.append(
            Status(
                "noise",
                f"the dent shifts the screen points by {exact_mm:.3g} mm, not above the "
                f"{floor:.3g} mm two noisy decodes of the defect-free scene differ by near it"
                + hint,
            )
        )
    in_region = int((failed & region).sum())
    if in_region:
        found.append(
            Status(
                "noise",
                f"{in_region} pixels of the dent's region fail to unwrap (noise or a "
                "period ratio too large for it)",
            )
        )
    return combined(found)


def _pmd_edge(scene: Scene, region: np.ndarray, shot: Capture) -> Status:
    covered = coverage_edge(scene)
    if covered is not None:
        return covered
    seen = interior(np.all(np.isfinite(shot.uv), axis=-1))  # its edge pixels straddle it
    where = touches_edge(region, seen)
    return Status("edge", f"the dent's region touches {where}") if where else Status()


def _pmd_resolution(scene: Scene, region: np.ndarray, decoding: Decoding) -> Status:
    count = int(region.sum())
    if not count:
        return Status()
    share = float((region & ~decoding.valid).sum() / count)
    if share <= INVALID_SHARE:
        return Status()
    finest = fringes_of(scene).periods[0]
    said = f"{share:.0%} of the dent's region has a modulation below {decoding.threshold:.3g}: "
    finish = finish_share(scene, region, finest, tuple(coded_axes(scene)))
    if finish is not None and finish.share < FINISH_CAUSE_SHARE:
        return Status(
            "unresolved",
            said + finish.phrase(finest) + " (a longer emitter.periods[0], a smoother finish "
            "or a screen nearer the part resolves them)",
        )
    return Status(
        "unresolved",
        said + f"the pixels average the {finest:g} mm fringes out there (a longer "
        "emitter.periods[0], a sharper focus or a finer camera resolves them)",
    )


def _pmd_exposure(baseline: PmdBaseline) -> Status:
    """``saturated``/``underexposed`` from the brightest fringe's noise-free signal,
    ``gain`` × radiance: the share of the range above the black level it fills (the full
    well fills that range), so the black level is left out by construction."""
    signal = baseline.capture.white * baseline.capture.gain
    signal = signal * fringes_of(baseline.scene).brightest()
    seen = np.isfinite(signal) & (baseline.capture.white > 0)
    values = signal[seen]
    if not values.size:
        return Status()
    clipped = float((values >= 1.0).mean())
    if clipped > 0.01:
        return Status(
            "saturated",
            f"{clipped:.1%} of the seen pixels clip at full scale on the brightest fringe; "
            'lower camera.exposure or set it to "auto"',
        )
    peak = float(np.percentile(values, 99.5))
    if peak < 0.1:
        return Status(
            "underexposed",
            f"the fringes peak at {peak:.1%} of the range above the black level; raise "
            'camera.exposure or set it to "auto"',
        )
    return Status()


assert "unresolved" in STATUSES  # the statuses are the paper metric's, in its order


def measure_pmd(
    scene: Scene, *, renderer: Renderer | None = None, settings: PmdSettings | None = None
) -> PmdResult:
    """:func:`measure_pmd_scene` with a renderer of its own unless one is given."""
    settings = settings or PmdSettings()
    check_scene(scene)
    if renderer is not None:
        return measure_pmd_scene(renderer, scene, settings)
    from glshade.gpu.renderer import Renderer

    with Renderer() as own:
        return measure_pmd_scene(own, scene, settings)


#: The numbers of the dent itself: a status other than ok makes them unreadable (the
#: station's own numbers, its noise, decoding error and valid share, stay readable).
DENT_COLUMNS = (
    "pmd_shift_mm",
    "pmd_snr",
    "pmd_slope_urad",
    "pmd_depth_um",
    "pmd_sigma_mm",
)


def pmd_concerns(status: str, column: str) -> bool:
    """True when ``status`` makes ``column`` of a PMD record unreadable."""
    return status != "ok" and column in DENT_COLUMNS


def summary(result: PmdResult) -> dict[str, Any]:
    """The result's numbers (no maps)."""
    return {
        name: getattr(result, name)
        for name in PmdResult.__dataclass_fields__
        if name not in ("maps", "seconds")
    }
