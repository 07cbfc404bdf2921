"""Whether a measured number can be trusted: the status every measurement carries.

``ok``, or the reason the number cannot be read, checked in this order (the first that
applies is the status; every one that applies is in the reason):

- ``outside``: no pixel that sees the emitter moves: the dent is not seen; or the scene
  has no dent at all (``defect.dmax = 0``, :func:`no_dent`: the same answer from every
  instrument).
- ``edge``: the dent's region in the image (where it moves the emitter map by at least
  :data:`REGION_SHARE` of its largest move) touches the image's border or the edge of
  the region that sees the emitter, or (a height map) unmeasured samples or
  the map's edge; or the largest contour shift lies away from that region (a
  discontinuity moved it, not the dent).
- ``unresolved``: more than :data:`UNRESOLVED_SHARE` of the dent's region spans fewer
  than the metric's ``min_period_px`` per stripe period; the reason names the shortest
  period that resolves there (the magnification closed form,
  :mod:`glshade.components.image_scale`).
- ``saturated`` / ``underexposed``: with a sensor, the defect-free recorded image clips at
  full scale in more than :data:`SATURATED_SHARE` of the seen pixels, or its stripes peak
  below :data:`UNDEREXPOSED_PEAK` of full scale.
- ``noise``: the paper's metric is not above the noise floor (two noisy exposures of the
  defect-free scene differ by as much).

``outside`` and ``edge`` make every number of the case unreadable; the others concern the
paper's metric only (:func:`concerns`): the continuous limit and the deflection follow the
rays, which neither the sensor's pixels nor its noise touch.

Pure functions of the maps, images and closed forms: :func:`assess` is called by
:mod:`glshade.measure.single` for every measured case.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

import numpy as np

if TYPE_CHECKING:
    from glshade.metrics.visibility import Baseline, Pattern, Visibility
    from glshade.scene import Scene

STATUSES = ("ok", "outside", "edge", "unresolved", "saturated", "underexposed", "noise")
#: Statuses that concern the paper's metric only (``visibility_px``: the stripes as a
#: viewer sees them); the continuous numbers follow the rays and stay readable.
IMAGE_ONLY = ("unresolved", "saturated", "underexposed", "noise")


def concerns(status: str, column: str) -> bool:
    """True when ``status`` makes ``column`` (``visibility_px``,
    ``visibility_continuous_px``, ``deflection_px``) unreadable."""
    if status == "ok":
        return False
    return column == "visibility_px" or status not in IMAGE_ONLY


#: The dent's region: pixels the dent moves by at least this share of its largest move.
REGION_SHARE = 0.2
#: A dent whose largest move is below this (px) is not seen at all.
SEEN_PX = 1e-6
#: The unresolved share of the dent's region above which its number cannot be read.
UNRESOLVED_SHARE = 0.25
#: Share of the seen pixels at full scale above which the sensor image is saturated.
SATURATED_SHARE = 0.01
#: The stripes' peak (99.5th percentile of the seen pixels, share of full scale) below
#: which the sensor image is underexposed.
UNDEREXPOSED_PEAK = 0.1


@dataclass(frozen=True)
class Status:
    """A measurement's ``status`` (one of :data:`STATUSES`) and, unless ``ok``, why:
    ``reason``, one line that names what to change."""

    status: str = "ok"
    reason: str = ""

    @property
    def ok(self) -> bool:
        return self.status == "ok"


@dataclass(frozen=True)
class Region:
    """The dent's region in the image: a boolean mask (H×W) and its largest move (px)."""

    mask: np.ndarray
    peak_px: float
    box: tuple[slice, slice] | None = None

    def pixels(self) -> tuple[np.ndarray, np.ndarray]:
        """The rows and columns of the region's pixels (looked for in its box only)."""
        if self.box is None:
            rows, cols = np.nonzero(self.mask)
            return rows, cols
        rows, cols = np.nonzero(self.mask[self.box])
        return rows + self.box[0].start, cols + self.box[1].start


#: The dent's window reaches this many standard deviations from its centre.
WINDOW_SIGMAS = 3.0


def dent_window(scene: Scene, shape: tuple[int, int]) -> np.ndarray:
    """Pixels near the dent: the bounding box of its ``WINDOW_SIGMAS`` ellipse on the
    surface, projected through the pinhole (lens distortion neglected, so the box is
    padded by 3 px and a tenth of its size), as a boolean mask of ``shape``."""
    defect = scene.defect
    turns = np.linspace(0.0, 2.0 * np.pi, 24, endpoint=False)
    cov = np.array([[defect.sigma_x2, defect.sigma_xz], [defect.sigma_xz, defect.sigma_z2]])
    ring = WINDOW_SIGMAS * np.linalg.cholesky(cov) @ np.stack([np.cos(turns), np.sin(turns)])
    x = np.concatenate([[defect.x0], defect.x0 + ring[0]])
    z = np.concatenate([[defect.z0], defect.z0 + ring[1]])
    box = surface_box(scene, shape, x, z)
    return np.zeros(shape, bool) if box is None else box


def surface_box(
    scene: Scene, shape: tuple[int, int], x: np.ndarray, z: np.ndarray
) -> np.ndarray | None:
    """The bounding box, in an image of ``shape``, of the surface's points at ``(x, z)``
    (mm) projected through the pinhole, padded by 3 px and a tenth of its size (lens
    distortion neglected), as a boolean mask (all False where the box misses the image);
    None where a point is behind the camera or off the surface."""
    cam = scene.camera
    y = np.asarray(scene.active.surface.height(scene, x, z), np.float64)
    pose = scene.camera_pose()
    d = np.stack([x, y, z], axis=-1) - pose.position
    depth = d @ pose.forward
    mask = np.zeros(shape, bool)
    if not np.all(depth > 0):
        return None
    (pitch_x, pitch_y), (cx, cy) = cam.pitch_xy, cam.centre_px
    sx = cam.focal * (d @ pose.right) / depth / pitch_x
    sy = cam.focal * (d @ pose.up) / depth / pitch_y
    cols, rows = sx + cx - 0.5, cy - 0.5 - sy
    if not (np.all(np.isfinite(cols)) and np.all(np.isfinite(rows))):
        return None
    pad_c = 3.0 + 0.1 * (cols.max() - cols.min())
    pad_r = 3.0 + 0.1 * (rows.max() - rows.min())
    r0, r1 = math.floor(rows.min() - pad_r), math.ceil(rows.max() + pad_r)
    c0, c1 = math.floor(cols.min() - pad_c), math.ceil(cols.max() + pad_c)
    height, width = shape
    if r1 < 0 or c1 < 0 or r0 >= height or c0 >= width:
        return mask
    mask[max(r0, 0) : min(r1 + 1, height), max(c0, 0) : min(c1 + 1, width)] = True
    return mask


def _box(mask: np.ndarray) -> tuple[slice, slice] | None:
    """The bounding box of a mask's True pixels (None: none)."""
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    if not len(rows):
        return None
    return slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1)


def dent_region(v0: np.ndarray, v1: np.ndarray, window: np.ndarray) -> Region:
    """Where, inside its ``window``, the dent moves the emitter map: ``|v1 - v0|`` in rows
    of the defect-free map (``|∂v0/∂row|`` mm per row) at least :data:`REGION_SHARE` of its
    largest value there. (Outside the window a discontinuity, a height map's step, may
    move the map by a hair's breadth of the dent's tail: not the dent's region.) Computed
    in the window's box only."""
    region = np.zeros(np.shape(v0), bool)
    box = _box(window)
    if box is None:
        return Region(region, 0.0)
    rows, cols = box
    grown = slice(max(rows.start - 1, 0), rows.stop + 1)  # the gradient's neighbours
    a = np.asarray(v0[grown, cols], np.float64)
    b = np.asarray(v1[grown, cols], np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        per_row = np.abs(np.gradient(a, axis=0)) if a.shape[0] > 1 else np.full(a.shape, np.nan)
        moved = np.abs(b - a) / per_row
    inner = slice(rows.start - grown.start, rows.start - grown.start + rows.stop - rows.start)
    moved = moved[inner]
    moved[~np.isfinite(moved) | ~window[rows, cols]] = 0.0
    peak = float(moved.max()) if moved.size else 0.0
    if peak < SEEN_PX:
        return Region(region, peak)
    region[rows, cols] = moved >= REGION_SHARE * peak
    return Region(region, peak, box)


def touches_edge(region: np.ndarray, seen: np.ndarray) -> str | None:
    """What of the image's or the seen region's edges the dent's region touches (words),
    or None. (The metric's cut columns are not an edge: contours are paired by stripe,
    so a dent wider than the kept columns still moves its stripes' contours measurably.)"""
    box = _box(region)
    if box is None:
        return None
    rows, cols = box
    height, width = region.shape
    if rows.start == 0 or cols.start == 0 or rows.stop == height or cols.stop == width:
        return "the image's border"
    around = slice(rows.start - 1, rows.stop + 1), slice(cols.start - 1, cols.stop + 1)
    if (_grown(region[around]) & ~seen[around]).any():
        return "the edge of the region that sees the emitter"
    return None


#: A largest shift of fewer pixels than this may tie with others anywhere (the metric's
#: whole pixels): where it lies says nothing.
PLACED_SHIFT_PX = 3.0


def _grown(mask: np.ndarray) -> np.ndarray:
    """``mask`` grown by one pixel in the eight directions."""
    padded = np.pad(mask, 1)
    height, width = mask.shape
    grown = np.zeros_like(mask)
    for dr in range(3):
        for dc in range(3):
            grown |= padded[dr : dr + height, dc : dc + width]
    return grown


def shift_away(region: Region, row: float, column: int, shift_px: float) -> float | None:
    """How far (px) a shift of ``shift_px`` at ``(row, column)`` lies from the dent's
    region when that is more than ``3 + peak / 2`` pixels, ``peak`` the dent's largest
    move (None when it lies in or near it, or when the shift is below
    :data:`PLACED_SHIFT_PX`)."""
    if shift_px < PLACED_SHIFT_PX or column < 0 or not math.isfinite(row):
        return None
    rows, cols = region.pixels()
    if not len(rows):
        return None
    gap = float(np.sqrt((rows - row) ** 2 + (cols - column) ** 2).min())
    return gap if gap > 3.0 + 0.5 * region.peak_px else None


def unresolved_share(region: np.ndarray, resolved: np.ndarray, seen: np.ndarray) -> float:
    """The share of the dent's seen region the metric leaves out as unresolved."""
    box = _box(region)
    if box is None:
        return 0.0
    region, resolved, seen = region[box], resolved[box], seen[box]
    inside = region & seen
    count = int(inside.sum())
    return float((inside & ~resolved).sum() / count) if count else 0.0


def exposure_problem(image: np.ndarray, seen: np.ndarray, black: float = 0.0) -> Status | None:
    """``saturated`` or ``underexposed`` from a recorded image (1 = full scale) over its
    seen pixels, or None; ``black``: the sensor's black level (recorded units), which
    the underexposure's peak is measured above, as a share of the range above it."""
    values = np.asarray(image, np.float64)[seen & np.isfinite(image)]
    if values.size == 0:
        return None
    clipped = float((values >= 1.0).mean())
    if clipped > SATURATED_SHARE:
        return Status(
            "saturated",
            f"{clipped:.1%} of the seen pixels clip at full scale; lower camera.exposure or "
            'set it to "auto"',
        )
    peak = float(np.percentile(values, 99.5) - black) / (1.0 - black)
    if peak < UNDEREXPOSED_PEAK:
        return Status(
            "underexposed",
            f"the stripes peak at {peak:.1%} of the range above the black level; raise "
            'camera.exposure or set it to "auto"',
        )
    return None


#: Stripe contrast below which a measurement is warned about (its causes named).
LOW_CONTRAST = 0.5


def michelson(values: np.ndarray) -> float:
    """``(hi - lo) / (hi + lo)`` of finite values, ``hi``/``lo`` their 99.5th and 0.5th
    percentiles (NaN for none)."""
    values = np.asarray(values, np.float64)
    values = values[np.isfinite(values)]
    if values.size == 0:
        return math.nan
    lo, hi = np.percentile(values, [0.5, 99.5])
    return float((hi - lo) / (hi + lo)) if hi + lo > 0 else 0.0


def stripe_contrast(image: np.ndarray, seen: np.ndarray, pattern: Pattern) -> float:
    """The stripes' Michelson contrast over the seen pixels of ``image``, relative to the
    emitter's own (``pattern``'s radiance over one period): 1 for a sharp mirror, less
    where defocus, a lobe or noise wash the stripes out (NaN where nothing is seen)."""
    own = michelson(pattern.radiance(np.linspace(0.0, pattern.period_mm, 1025), 0.0))
    return michelson(np.asarray(image)[seen]) / own if own > 0 else math.nan


def contrast_warning(contrast: float, causes: tuple[str, ...]) -> str | None:
    """The warning line for a measured stripe contrast below :data:`LOW_CONTRAST`."""
    if not contrast < LOW_CONTRAST:
        return None
    why = "; ".join(causes) if causes else "the stripes are finer than the optics resolve"
    return (
        f"the stripes' contrast is {contrast:.2f} of the emitter's: {why}; contours "
        "on washed-out stripes follow the binarisation level more than the dent"
    )


def combined(found: list[Status]) -> Status:
    """The first status found (in :data:`STATUSES` order), with every reason."""
    bad = sorted((s for s in found if not s.ok), key=lambda s: STATUSES.index(s.status))
    if not bad:
        return Status()
    return Status(bad[0].status, "; ".join(dict.fromkeys(s.reason for s in bad)))


# --------------------------------------------------------------------------- one case
def no_dent(scene: Scene) -> Status | None:
    """``outside`` for a scene without a dent (``defect.dmax = 0``), None for one with a
    dent: nothing moves, so no number of a dent can be read. Every instrument answers a
    scene without a dent with this one status and reason, before any other check."""
    if scene.defect.dmax != 0.0:
        return None
    return Status(
        "outside",
        "the scene has no dent (defect.dmax = 0): nothing moves, so there is no dent to "
        "measure (give defect.dmax a depth)",
    )


def assess(scene: Scene, baseline: Baseline, v1: np.ndarray, result: Visibility) -> Status:
    """The status of ``result``, the metric's measurement of ``scene``'s defect (emitter
    map ``v1``) against ``baseline`` (:class:`glshade.metrics.visibility.Baseline`)."""
    absent = no_dent(scene)
    if absent is not None:
        return absent
    v0 = baseline.v0
    seen = np.isfinite(v0)
    region = dent_region(v0, v1, dent_window(scene, v0.shape))
    if not region.mask.any():
        return Status(
            "outside",
            "the dent is not seen: no pixel that sees the emitter moves (move the dent, "
            "defect.x0/z0, or the camera)",
        )
    floor = result.noise_floor_px
    noisy = floor is not None and result.visibility_px <= floor
    # where a shift under the noise floor lies says nothing about the dent
    found = [_edge(scene, baseline, region, result, noisy), _unresolved(scene, baseline, region)]
    if scene.active.records(scene) and baseline.normal_images is not None:
        found.append(_exposure(scene, baseline, seen))
    if noisy:
        found.append(
            Status(
                "noise",
                f"{result.visibility_px:g} px is not above the noise floor of {floor:g} px "
                "(two noisy exposures of the defect-free scene differ by as much)",
            )
        )
    return combined(found)


def _exposure(scene: Scene, baseline: Baseline, seen: np.ndarray) -> Status:
    """``saturated``/``underexposed`` of the defect-free recorded image (once per
    baseline: every dent on it was exposed alike), an underexposure's causes named."""
    found = baseline.derived.get("exposure")
    if found is None:
        # assess() calls this only where the baseline has rendered images
        normal_images = cast("Callable[[float], np.ndarray]", baseline.normal_images)
        image = normal_images(float(baseline.phases[0]))
        found = exposure_problem(image, seen, scene.sensor.black_level) or Status()
        if found.status == "underexposed":
            causes = scene.active.dimming(scene)
            found = Status(found.status, found.reason + "".join(f"; {c}" for c in causes))
        baseline.derived["exposure"] = found
    return found


def coverage_edge(scene: Scene) -> Status | None:
    """``edge`` where the surface's measured data do not cover the dent (a height map's
    unmeasured samples in the dent's region, or the dent at the map's edge): the most
    specific reason, checked first by every instrument; None where they cover it."""
    coverage = scene.active.surface.coverage(scene)
    if coverage is not None and coverage.nan_near_dent:
        return Status(
            "edge",
            "unmeasured (NaN) samples of the height map lie in the dent's region (fill them: "
            'surface.fill = "harmonic" or "nearest")',
        )
    if coverage is not None and coverage.dent_at_edge:
        return Status("edge", "the dent's region reaches the height map's edge")
    return None


def _edge(
    scene: Scene, baseline: Baseline, region: Region, result: Visibility, noisy: bool
) -> Status:
    covered = coverage_edge(scene)
    if covered is not None:
        return covered
    where = touches_edge(region.mask, np.isfinite(baseline.v0))
    if where is not None:
        return Status("edge", f"the dent's region touches {where}")
    if noisy:
        return Status()
    shift = result.shift
    away = shift_away(region, shift.normal_row, shift.column, shift.distance_px)
    if away is not None:
        return Status(
            "edge",
            f"the largest contour shift ({shift.distance_px:g} px, row {shift.normal_row:.0f}, "
            f"column {shift.column}) lies {away:.0f} px from the dent's region: a discontinuity "
            "of the surface or of the seen region moved it, not the dent",
        )
    moved = np.asarray(result.displacement_px)
    if moved.size and np.isfinite(moved).any() and np.nanmax(moved) > 0.0:
        row, column = np.unravel_index(int(np.nanargmax(moved)), moved.shape)
        away = shift_away(region, float(row), int(column), float(moved[row, column]))
        if away is not None:
            return Status(
                "edge",
                f"the largest deflection ({moved[row, column]:.3g} px, row {row}, column "
                f"{column}) lies {away:.0f} px from the dent's region: a discontinuity of the "
                "surface or of the seen region moved the map there, not the dent",
            )
    return Status()


def _unresolved(scene: Scene, baseline: Baseline, region: Region) -> Status:
    from glshade.components import image_scale

    share = unresolved_share(region.mask, baseline.resolved, np.isfinite(baseline.v0))
    if share <= UNRESOLVED_SHARE:
        return Status()
    period = baseline.pattern.period_mm
    needed_px = baseline.settings.min_period_px
    spans = image_scale.period_px(scene, period)
    shortest = image_scale.smallest_resolved_period_mm(scene, needed_px)
    spans_text = f"span {spans:.1f} px per period at the dent" if math.isfinite(spans) else ""
    advice = (
        f'; a period of {shortest:.3g} mm or more resolves there (emitter.period = "auto" '
        f"picks {image_scale.auto_period_mm(scene):g} mm)"
        if math.isfinite(shortest)
        else "; use a longer emitter.period"
    )
    return Status(
        "unresolved",
        f"the {period:g} mm stripes {spans_text or 'are too fine at the dent'} (the metric needs "
        f"{needed_px:g}): {share:.0%} of the dent's region is left out{advice}",
    )
