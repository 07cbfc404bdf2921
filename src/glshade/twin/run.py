"""One twin run: the real measurement reconstructed, the twin rendered along both screen
axes, the two compared (docs/twin.md)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from glshade.capture.sofast import SofastCalibration, SofastMeasurement, decode_sofast
from glshade.capture.sofast_station import SofastDisplay, SofastStation
from glshade.scene import Scene
from glshade.twin import compare
from glshade.twin.reconstruct import (
    DESIGN_FOCAL_MM,
    FacetMeasurement,
    measure_facet,
    solve_facet,
)
from glshade.twin.scene import TwinFrames, twin_frames, twin_scene_dict

if TYPE_CHECKING:
    from glshade.rendering import Renderer

#: glshade's screen axis of each SOFAST direction.
AXIS_OF = {"x": "u", "y": "v"}


@dataclass(frozen=True)
class TwinRun:
    """``measured`` the real facet; ``twin_measured`` the twin's frames decoded and
    reconstructed the same way (None when not rendered); ``scenes`` the twin's scene per
    SOFAST direction;
    ``frames`` the twin's geometry; ``twin_screen_mm`` (H, W, 3) its exact screen points
    (None when not rendered); ``twin_radiance`` per direction (K, N, H, W), SOFAST's
    period order; ``real_frames`` the recorded frames alike; ``deviation``; ``beside``
    the frames' numbers; ``summary``."""

    measured: FacetMeasurement
    twin_measured: FacetMeasurement | None
    scenes: dict[str, Scene]
    frames: TwinFrames
    twin_screen_mm: NDArray[np.float64] | None
    twin_radiance: dict[str, NDArray[np.float64]]
    real_frames: dict[str, NDArray[np.float64]]
    deviation: compare.Deviation
    beside: dict[str, Any]
    summary: dict[str, Any]


def run_twin(
    station: SofastStation,
    measurement: SofastMeasurement,
    calibration: SofastCalibration | None,
    renderer: Renderer | None,
    surface: str = "nominal",
    design_focal_mm: tuple[float, float] = DESIGN_FOCAL_MM,
    supersample: int = 1,
) -> TwinRun:
    """Reconstruct, render (when a ``renderer`` is given) and compare."""
    from glshade.instruments.pmd.capture import capture

    measured = measure_facet(station, measurement, calibration, design_focal_mm=design_focal_mm)
    frames = twin_frames(station, measured)
    scenes = {
        d: Scene.from_dict(
            twin_scene_dict(
                station, measurement, measured, surface, design_focal_mm, AXIS_OF[d], supersample
            )
        )
        for d in ("x", "y")
    }
    screen: NDArray[np.float64] | None = None
    twin_measured: FacetMeasurement | None = None
    radiance: dict[str, NDArray[np.float64]] = {}
    beside: dict[str, Any] = {}
    if renderer is not None:
        white = None
        for direction, scene in scenes.items():
            shot = capture(renderer, scene)
            block = shot.radiance.reshape(-1, measurement.shifts, *shot.radiance.shape[1:])
            radiance[direction] = np.asarray(block[::-1], np.float64)  # coarsest first
            if screen is None:
                screen = compare.twin_screen_points(shot.uv, scene.emitter_plane(), frames)
                white = np.asarray(shot.white, np.float64)
        assert white is not None
        twin_decoded = decode_sofast(twin_measurement(measurement, radiance, white), None)
        flat = dataclasses.replace(station, display=flat_display(station.display))
        twin_measured = solve_facet(flat, twin_decoded, measured.located, design_focal_mm)
        real_decoded = decode_sofast(measurement, None)  # the raw frames: their own residual
        beside = compare.frames_beside(measurement, real_decoded, twin_decoded, measured.mask)
    deviation = compare.deviation(measured, design_focal_mm, screen, twin_measured)
    summary = summary_of(measured, frames, deviation, beside, surface, design_focal_mm)
    summary["supersample"] = int(supersample)
    summary["twin_reconstructed"] = closed_loop(
        twin_measured, twin_surface(measured, surface, design_focal_mm)
    )
    summary["status"], summary["status_reason"] = trust(summary)

    return TwinRun(
        measured,
        twin_measured,
        scenes,
        frames,
        screen,
        radiance,
        real_blocks(measurement),
        deviation,
        beside,
        summary,
    )


def twin_measurement(
    measurement: SofastMeasurement,
    radiance: dict[str, NDArray[np.float64]],
    white: NDArray[np.float64],
) -> SofastMeasurement:
    """The twin's frames as a measurement of the station's: 0 to 255 of its white, black
    0, the station's frame order (the twin's own flat screen is the caller's)."""
    scale = 255.0 / float(np.max(white))
    frames = np.concatenate(
        [radiance[d].reshape(-1, *white.shape) for d in measurement.direction_order]
    )
    return dataclasses.replace(
        measurement, frames=frames * scale, black=np.zeros_like(white), white=white * scale
    )


def flat_display(display: SofastDisplay) -> SofastDisplay:
    """The flat rectangle nearest ``display`` (its affine fit), as a display shape."""
    matrix, offset, _ = display.affine()
    points = matrix @ display.fractions + offset[:, None]
    return SofastDisplay(fractions=display.fractions, points_mm=points, name="flat fit")


def real_blocks(measurement: SofastMeasurement) -> dict[str, NDArray[np.float64]]:
    """The recorded frames per direction (K, N, H, W), SOFAST's period order."""
    out = {}
    start = 0
    shifts = measurement.shifts
    for direction in measurement.direction_order:
        count = len(measurement.periods_x if direction == "x" else measurement.periods_y)
        block = measurement.frames[start : start + count * shifts].astype(np.float64)
        out[direction] = block.reshape(count, shifts, *block.shape[1:])
        start += count * shifts
    return out


def twin_surface(
    measured: FacetMeasurement, surface: str, design_focal_mm: tuple[float, float]
) -> NDArray[np.float64]:
    """The twin's facet as parabola coefficients (F, D, A, E, C, B), mm."""
    if surface == "fitted":
        return np.asarray(measured.solution.surface, np.float64)
    return np.array(
        [0.0, 0.0, 1 / (4 * design_focal_mm[0]), 0.0, 0.0, 1 / (4 * design_focal_mm[1])]
    )


def closed_loop(
    twin: FacetMeasurement | None, surface: NDArray[np.float64]
) -> dict[str, Any] | None:
    """The twin's frames decoded and solved like the real ones, against the surface the
    twin was rendered with: its focal lengths and its slopes' rms and largest error."""
    if twin is None:
        return None
    error = twin.solution.slopes - compare.parabola_slopes(surface, twin.solution.points_mm)
    fx, fy = twin.focal_lengths_mm
    return {
        "pixels": int(twin.mask.sum()),
        "focal_lengths_m": [fx / 1000, fy / 1000],
        "slope_error_rms_mrad": [float(v) for v in np.sqrt(np.mean(error**2, axis=1)) * 1e3],
        "slope_error_max_mrad": [float(v) for v in np.max(np.abs(error), axis=1) * 1e3],
    }


#: What a reconstruction must meet to be trusted: the corners' reprojection (px) and the
#: closed chain's slope error (mrad rms; SOFAST's stated accuracy).
MAX_REPROJECTION_PX, MAX_LOOP_MRAD = 1.0, 0.05


def trust(summary: dict[str, Any]) -> tuple[str, str]:
    """``(status, reason)``: "ok" where the corners reproject within
    :data:`MAX_REPROJECTION_PX` and the twin's chain closes within :data:`MAX_LOOP_MRAD`;
    "unchecked" without a twin rendered; "unreliable" with the reasons otherwise."""
    reasons = []
    if summary["reprojection_px"] > MAX_REPROJECTION_PX:
        reasons.append(f"the corners reproject {summary['reprojection_px']:.2f} px (> 1 px)")
    loop = summary.get("twin_reconstructed")
    if loop is not None and max(loop["slope_error_rms_mrad"]) > MAX_LOOP_MRAD:
        worst = max(loop["slope_error_rms_mrad"])
        reasons.append(f"the twin's chain closes to {worst:.3f} mrad rms (> {MAX_LOOP_MRAD} mrad)")
    if reasons:
        return "unreliable", "; ".join(reasons)
    if loop is None:
        return "unchecked", "no twin rendered: the chain's closure is not checked"
    return "ok", ""


def summary_of(
    measured: FacetMeasurement,
    frames: TwinFrames,
    deviation: compare.Deviation,
    beside: dict[str, Any],
    surface: str,
    design_focal_mm: tuple[float, float],
) -> dict[str, Any]:
    """The numbers of ``summary.json``."""
    pose = measured.pose
    fx, fy = measured.focal_lengths_mm
    screen = deviation.screen_mm
    rendered = bool(np.isfinite(screen).any())
    return {
        "pixels": int(measured.mask.sum()),
        "lit_pixels": int(measured.raw_mask.sum()),
        "focal_lengths_m": [fx / 1000, fy / 1000],
        "design_focal_lengths_m": [design_focal_mm[0] / 1000, design_focal_mm[1] / 1000],
        "corners_px": pose.corners_px.tolist(),
        "reprojection_px": pose.reprojection_px,
        "camera_in_facet_mm": pose.camera_in_facet_mm.tolist(),
        "distance_scale": pose.distance_scale,
        "alignment_turn_mrad": float(
            np.arccos(np.clip((np.trace(measured.solution.alignment[:3, :3]) - 1) / 2, -1, 1)) * 1e3
        ),
        "slope_rms_from_design_mrad": compare.rms_mrad(deviation.from_design),
        "slope_rms_from_fit_mrad": compare.rms_mrad(deviation.from_fit),
        "slope_rms_from_twin_mrad": compare.rms_mrad(deviation.from_twin) if rendered else None,
        "twin_surface": surface,
        "screen_shape_rms_mm": frames.shape_rms_mm,
        "screen_deviation_rms_mm": (
            [float(np.sqrt(np.nanmean(v**2))) for v in screen] if rendered else None
        ),
        "screen_deviation_mean_mm": ([float(np.nanmean(v)) for v in screen] if rendered else None),
        "frames": beside or None,
    }
