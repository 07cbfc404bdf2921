"""Where the facet is: its mask in the image, its corners, and the camera-facet pose,
found from the measurement the way SOFAST finds them (docs/twin.md).

1. the mask: white - black above a threshold half-way between the histogram's dark and
   light peaks, smoothed by a 9 x 9 vote, its largest region kept;
2. the expected pose: the mask's centroid pixel at the distance that puts it
   ``dist_optic_screen`` from the screen, the facet turned to reflect the camera into
   the screen (the bisector), its corners projected;
3. the corners: one line per side, fitted (RANSAC at 2 px, then least squares) to the
   mask's edge points near the expected side; the corners are where the lines cross;
4. the pose: ``cv2.solvePnP`` of the facet's corners, then its distance scaled so the
   measure point lies ``dist_optic_screen`` from the screen's origin.

Lengths in mm; pixels in OpenCV's convention (integer index = pixel centre).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from glshade.capture.masks import largest_region, lit_mask
from glshade.capture.sofast_station import SofastStation
from glshade.errors import GlshadeError
from glshade.numerics import nearest_root
from glshade.poses import rodrigues, rotation_between

#: The edge points searched for each side: along it beyond its ends, and across it (px).
SIDE_SEARCH_PX = (50.0, 50.0)
RANSAC_PX = 2.0


@dataclass(frozen=True)
class FacetPose:
    """The camera-facet pose: a facet point p is ``rotation @ p + translation_mm`` in
    camera coordinates (OpenCV's ``solvePnP`` sense); ``corners_px`` (4, 2) the corners
    found, ``reprojection_px`` their rms reprojection error, ``distance_scale`` the
    factor the distance refinement applied."""

    rotation: NDArray[np.float64]
    translation_mm: NDArray[np.float64]
    corners_px: NDArray[np.float64]
    reprojection_px: float
    distance_scale: float

    @property
    def camera_in_facet_mm(self) -> NDArray[np.float64]:
        """The camera's centre in facet coordinates (mm)."""
        return np.asarray(-self.rotation.T @ self.translation_mm, np.float64)


def raw_mask(black: NDArray[np.generic], white: NDArray[np.generic]) -> NDArray[np.bool_]:
    """The lit pixels (:func:`glshade.capture.masks.lit_mask`) of the largest region."""
    lit = lit_mask(black, white)
    return lit & largest_region(lit)


def edge_points(mask: NDArray[np.bool_]) -> NDArray[np.float64]:
    """(N, 2) (column, row) points on the mask's boundary, on the pixel edges: a pixel
    whose upper (left) neighbour differs from it gives the edge between them, at
    (column - 0.5, row - 0.5), as SOFAST's edge filter does."""
    m = mask.astype(np.int8)
    up = np.concatenate([m[1:2], m[:-1]], axis=0)  # reflected at the border
    left = np.concatenate([m[:, 1:2], m[:, :-1]], axis=1)
    edge = (m != up) | (m != left)
    rows, cols = np.nonzero(edge)
    return np.stack([cols - 0.5, rows - 0.5], axis=1).astype(np.float64)


def expected_pose(
    station: SofastStation, mask: NDArray[np.bool_], dist_optic_screen_mm: float
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """SOFAST's first guess ``(rotation, translation_mm)``: the mask's centroid at the
    distance from the screen, the facet's normal the bisector of camera and screen."""
    rows, cols = np.nonzero(mask)
    ray = station.camera.rays(np.array([cols.mean()]), np.array([rows.mean()]))[0]
    screen = np.asarray(station.v_cam_screen_cam_mm, np.float64)
    # the facet ahead, dist_optic_screen from the screen: |along ray - screen| = distance
    ahead = float(ray @ screen)
    reach = ahead**2 - float(screen @ screen) + dist_optic_screen_mm**2
    if reach < 0:
        raise GlshadeError("facet pose: no point along the facet's ray is that far from the screen")
    centre = ray * (ahead + np.sqrt(reach))
    to_camera = -centre / np.linalg.norm(centre)
    to_screen = (screen - centre) / np.linalg.norm(screen - centre)
    normal = (to_camera + to_screen) / np.linalg.norm(to_camera + to_screen)
    camera_to_facet = rotation_between(to_camera, normal) @ rodrigues(np.array([np.pi, 0, 0]))
    rotation = np.asarray(camera_to_facet.T, np.float64)
    translation = centre - rotation @ station.facet.centroid_mm
    return rotation, translation


def fit_line(points: NDArray[np.float64], seed: int = 1) -> tuple[NDArray[np.float64], float]:
    """A line ``n . p = c`` (unit n) through ``points`` (N, 2): of up to 1000 lines
    through two points drawn from a seeded Mersenne Twister (SOFAST's draws, so its
    inliers), the one with the most points within :data:`RANSAC_PX`, refitted by least
    squares (perpendicular distance) to those points."""
    if len(points) <= 15:
        raise GlshadeError(f"facet edge: {len(points)} edge points on a side, more than 15 needed")
    draws = np.random.RandomState(np.random.MT19937(np.random.SeedSequence(seed)))
    count = len(points)
    best = np.zeros(count, bool)
    for _ in range(1000):
        i = int(np.floor(draws.rand() * count))
        j = int(np.floor(draws.rand() * count))
        while np.array_equal(points[i], points[j]):
            j = int(np.floor(draws.rand() * count))
        d = points[j] - points[i]
        near = np.abs((points - points[i]) @ (np.array([d[1], -d[0]]) / np.hypot(*d))) < RANSAC_PX
        if near.sum() > best.sum():
            best = near
        if near.sum() > int(0.99 * count):
            break
    inliers = points[best]
    centre = inliers.mean(axis=0)
    normal = np.linalg.svd(inliers - centre)[2][1]
    return normal, float(normal @ centre)


def refine_corners(
    expected_px: NDArray[np.float64], edges: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The corners (4, 2) where the sides' fitted lines cross; side i runs from
    expected corner i to i+1, corner i is where side i-1 meets side i."""
    along_px, across_px = SIDE_SEARCH_PX
    lines = []
    for i in range(4):
        p1, p2 = expected_px[i], expected_px[(i + 1) % 4]
        axis = (p2 - p1) / np.linalg.norm(p2 - p1)
        rel = edges - p1
        t = rel @ axis
        s = rel @ np.array([-axis[1], axis[0]])
        near = (t > -along_px) & (t < np.linalg.norm(p2 - p1) + along_px) & (np.abs(s) < across_px)
        lines.append(fit_line(edges[near]))
    corners = []
    for i in range(4):
        (n1, c1), (n2, c2) = lines[i - 1], lines[i]
        corners.append(np.linalg.solve(np.stack([n1, n2]), np.array([c1, c2])))
    return sorted_corners(np.array(corners))


def sorted_corners(corners_px: NDArray[np.float64]) -> NDArray[np.float64]:
    """The corners ordered by their angle about their centroid, from the image's +x axis
    toward +y (rows down): the order SOFAST pairs with the facet definition's corners."""
    rel = corners_px - corners_px.mean(axis=0)
    return corners_px[np.argsort(np.mod(np.arctan2(rel[:, 1], rel[:, 0]), 2 * np.pi))]


def polygon_mask(corners_px: NDArray[np.float64], shape: tuple[int, int]) -> NDArray[np.bool_]:
    """Pixel centres inside the polygon ``corners_px`` (4, 2)."""
    from matplotlib.path import Path as PolygonPath

    rows, cols = np.mgrid[0 : shape[0], 0 : shape[1]]
    inside = PolygonPath(corners_px).contains_points(np.stack([cols.ravel(), rows.ravel()], 1))
    return np.asarray(inside.reshape(shape), bool)


def facet_pose(
    station: SofastStation,
    mask: NDArray[np.bool_],
    dist_optic_screen_mm: float,
    measure_point_mm: NDArray[np.float64],
) -> FacetPose:
    """The camera-facet pose from the mask (module docstring, steps 2-4)."""
    import cv2

    rot0, t0 = expected_pose(station, mask, dist_optic_screen_mm)
    corners3 = station.facet.corners_mm
    expected_px = station.camera.project(
        corners3, np.asarray(cv2.Rodrigues(rot0)[0], np.float64).ravel(), t0
    )
    corners_px = refine_corners(expected_px, edge_points(mask))
    ok, rvec, tvec = cv2.solvePnP(
        corners3, corners_px, station.camera.matrix, station.camera.distortion
    )
    if not ok:
        raise GlshadeError("facet pose: cv2.solvePnP found no pose for the facet's corners")
    rotation = rodrigues(rvec)
    translation = np.asarray(tvec, np.float64).ravel()
    reproj = (
        station.camera.project(corners3, np.asarray(rvec, np.float64), translation) - corners_px
    )
    measure = rotation @ measure_point_mm
    screen = np.asarray(station.v_cam_screen_cam_mm, np.float64)
    # |screen - (scale t + m)| = d, the root nearest 1
    gap = screen - measure
    scale = nearest_root(
        float(translation @ translation),
        -float(translation @ gap),
        float(gap @ gap) - dist_optic_screen_mm**2,
        1.0,
    )
    if not np.isfinite(scale):
        raise GlshadeError(
            "facet pose: no distance puts the measure point that far from the screen"
        )
    return FacetPose(
        rotation=rotation,
        translation_mm=translation * scale,
        corners_px=corners_px,
        reprojection_px=float(np.sqrt(np.mean(np.sum(reproj**2, axis=1)))),
        distance_scale=float(scale),
    )
