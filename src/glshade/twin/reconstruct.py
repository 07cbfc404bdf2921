"""A real SOFAST measurement reconstructed end to end by glshade (docs/twin.md): the
frames decoded by glshade's decoder, the facet found in the image, its decoded screen
points placed on the calibrated screen, and its slopes solved SOFAST's way."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from glshade.capture.sofast import (
    SofastCalibration,
    SofastDecoded,
    SofastMeasurement,
    decode_sofast,
)
from glshade.capture.sofast_station import SofastStation
from glshade.errors import GlshadeError
from glshade.twin import geometry
from glshade.twin.slopes import SlopeInputs, SlopeSolution, solve

#: The design focal lengths (mm) SOFAST's example starts the parabola from.
DESIGN_FOCAL_MM = (100_000.0, 100_000.0)


@dataclass(frozen=True)
class FacetMeasurement:
    """The facet as measured: ``mask`` (H, W) the pixels reconstructed (lit, inside the
    fitted facet outline, decoded, on the calibrated screen); ``fraction`` (2, H, W) the
    decoded screen fractions (SOFAST's x, y); ``screen_mm`` (H, W, 3) their points in
    screen coordinates; ``pose`` the camera-facet pose; ``solution`` the slope solver's
    result on ``mask``'s pixels in row-major order; ``slopes`` (2, H, W) dz/dx, dz/dy
    (NaN off the mask); ``raw_mask`` the lit pixels; ``located`` where the facet was
    found."""

    mask: NDArray[np.bool_]
    raw_mask: NDArray[np.bool_]
    fraction: NDArray[np.float64]
    screen_mm: NDArray[np.float64]
    pose: geometry.FacetPose
    solution: SlopeSolution
    slopes: NDArray[np.float64]
    dist_optic_screen_mm: float
    located: Located

    @property
    def focal_lengths_mm(self) -> tuple[float, float]:
        """The fitted parabola's focal lengths (x, y), mm."""
        return self.solution.focal_lengths_mm


def measure_facet(
    station: SofastStation,
    measurement: SofastMeasurement,
    calibration: SofastCalibration | None,
    measure_point_mm: NDArray[np.float64] | None = None,
    design_focal_mm: tuple[float, float] = DESIGN_FOCAL_MM,
) -> FacetMeasurement:
    """Decode, locate and solve one single-facet measurement."""
    decoded = decode_sofast(measurement, calibration)
    lit = geometry.raw_mask(measurement.black, measurement.white)
    point = np.asarray(
        measurement.measure_point_mm if measure_point_mm is None else measure_point_mm, float
    )
    pose = geometry.facet_pose(station, lit, measurement.dist_optic_screen_mm, point)
    inside = lit & geometry.polygon_mask(pose.corners_px, lit.shape)
    located = Located(lit, inside, pose, measurement.dist_optic_screen_mm, point)
    return solve_facet(station, decoded, located, design_focal_mm)


@dataclass(frozen=True)
class Located:
    """Where the facet is: ``lit`` the pixels that see the lit screen, ``inside`` those
    inside its fitted outline, ``pose``, the measured ``distance_mm`` of the measure point
    ``point_mm`` (facet coordinates) from the screen's origin."""

    lit: NDArray[np.bool_]
    inside: NDArray[np.bool_]
    pose: geometry.FacetPose
    distance_mm: float
    point_mm: NDArray[np.float64]


def solve_facet(
    station: SofastStation,
    decoded: SofastDecoded,
    located: Located,
    design_focal_mm: tuple[float, float] = DESIGN_FOCAL_MM,
) -> FacetMeasurement:
    """The slopes of a located facet from its decoded screen fractions."""
    pose, lit = located.pose, located.lit
    fraction = np.stack([decoded.x, decoded.y])
    screen = np.full((*lit.shape, 3), np.nan)
    decodable = located.inside & decoded.valid
    screen[decodable] = station.display.screen_mm(decoded.x[decodable], decoded.y[decodable])
    mask = decodable & np.all(np.isfinite(screen), axis=-1)
    if mask.sum() < 16:
        raise GlshadeError(f"{mask.sum()} facet pixels decoded on the screen; too few to solve")
    rows, cols = np.nonzero(mask)
    to_facet = pose.rotation.T  # camera -> facet directions
    rot_sc, t_sc = station.screen_to_camera()
    screen_cam = screen[mask] @ rot_sc.T + t_sc
    measure = to_facet @ (pose.rotation @ located.point_mm + pose.translation_mm)
    inputs = SlopeInputs(
        rays=station.camera.rays(cols, rows) @ to_facet.T,
        screen_mm=(screen_cam - pose.translation_mm) @ to_facet.T,
        camera_mm=pose.camera_in_facet_mm,
        screen_origin_mm=to_facet @ (t_sc - pose.translation_mm),
        measure_ray=measure / np.linalg.norm(measure),
        align_mm=station.facet.centroid_mm,
        distance_mm=located.distance_mm,
        focal_mm=design_focal_mm,
    )
    solution = solve(inputs)
    slopes = np.full((2, *lit.shape), np.nan)
    slopes[:, mask] = solution.slopes
    return FacetMeasurement(
        mask=mask,
        raw_mask=lit,
        fraction=fraction,
        screen_mm=screen,
        pose=pose,
        solution=solution,
        slopes=slopes,
        dist_optic_screen_mm=located.distance_mm,
        located=located,
    )
