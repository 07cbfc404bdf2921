"""The twin's reconstruction: SOFAST's slope solver reproduced (on SOFAST's own inputs
and on a parabola whose slopes are known by construction), and the whole real
measurement reconstructed by glshade against SOFAST's published results."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from glshade.twin.slopes import SlopeInputs, solve

pytest.importorskip("h5py")


def _data() -> Path:
    here = Path(__file__).resolve().parents[1]
    for cand in (here.parent / "shared" / "sofast", here / "shared" / "sofast"):
        if (cand / "measurement_facet.h5").exists():
            return cand
    pytest.skip("SOFAST data (shared/sofast) absent")


def _expected(key: str) -> np.ndarray:
    import h5py

    with h5py.File(_data() / "expected_facet.h5", "r") as h5:
        return np.asarray(h5["DataSofastCalculation/facet/facet_000/" + key][()])


def _reflect(points, normals, camera):
    into = points - camera
    into /= np.linalg.norm(into, axis=1, keepdims=True)
    return into - 2 * (into * normals).sum(1, keepdims=True) * normals


def test_the_solver_recovers_a_known_parabola() -> None:
    """Screen points traced from a parabola z = x^2/4f + y^2/4g (f = 80 m, g = 120 m)
    by exact reflection: the solver, started from 100 m, returns its slopes and its
    focal lengths."""
    f, g = 80_000.0, 120_000.0
    xs, ys = np.meshgrid(np.linspace(-500, 500, 41), np.linspace(-500, 500, 41))
    points = np.stack(
        [xs.ravel(), ys.ravel(), xs.ravel() ** 2 / (4 * f) + ys.ravel() ** 2 / (4 * g)], 1
    )
    normals = np.stack([-points[:, 0] / (2 * f), -points[:, 1] / (2 * g), np.ones(len(points))], 1)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    camera = np.array([-2000.0, 400.0, 9000.0])
    out = _reflect(points, normals, camera)
    plane_z = 9500.0  # a screen plane z = const, in front of the facet
    screen = points + out * ((plane_z - points[:, 2]) / out[:, 2])[:, None]
    rays = points - camera
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    origin = np.array([1500.0, 0.0, plane_z])
    measure = -camera / np.linalg.norm(camera)
    inputs = SlopeInputs(
        rays=rays,
        screen_mm=screen,
        camera_mm=camera,
        screen_origin_mm=origin,
        measure_ray=measure,
        align_mm=np.zeros(3),
        distance_mm=float(np.linalg.norm(origin)),
        focal_mm=(100_000.0, 100_000.0),
    )
    sol = solve(inputs)
    truth = np.stack([points[:, 0] / (2 * f), points[:, 1] / (2 * g)])
    assert np.max(np.abs(sol.slopes - truth)) < 1e-9
    assert np.allclose(sol.focal_lengths_mm, (f, g), rtol=1e-6)
    assert np.allclose(sol.alignment, np.eye(4), atol=1e-6)


def test_the_solver_reproduces_sofast_on_its_inputs() -> None:
    """Fed SOFAST's own geometry (expected_facet.h5), the solver returns SOFAST's slopes
    and surface to round-off."""
    import cv2

    geo = "CalculationDataGeometryFacet/"
    rot = cv2.Rodrigues(_expected(geo + "SpatialOrientation/r_cam_optic").reshape(3, 1))[0]
    cam_optic = 1000 * _expected(geo + "SpatialOrientation/v_cam_optic_cam").ravel()
    cam_screen = 1000 * _expected(geo + "SpatialOrientation/v_cam_screen_cam").ravel()
    camera = -rot @ cam_optic
    inputs = SlopeInputs(
        rays=_expected(geo + "u_pixel_pointing_facet").T,
        screen_mm=1000 * _expected(geo + "v_screen_points_facet").T,
        camera_mm=camera,
        screen_origin_mm=camera + rot @ cam_screen,
        measure_ray=_expected(geo + "u_cam_measure_point_facet").ravel(),
        align_mm=np.zeros(3),
        distance_mm=1000 * float(_expected(geo + "measure_point_screen_distance")),
        focal_mm=(100_000.0, 100_000.0),
    )
    sol = solve(inputs)
    assert np.max(np.abs(sol.slopes - _expected("SlopeSolverData/slopes_facet_xy"))) < 1e-12
    surf = _expected("SlopeSolverData/surf_coefs_facet")
    assert np.allclose(sol.surface[[2, 4, 5]] * 1000, surf[[2, 4, 5]], rtol=1e-9)
    assert np.allclose(
        sol.alignment[:3, :3], _expected("SlopeSolverData/trans_alignment")[:3, :3], atol=1e-12
    )


@pytest.fixture(scope="module")
def measured():
    from glshade.capture.sofast import read_sofast_calibration, read_sofast_measurement
    from glshade.capture.sofast_station import STATION_FILES, read_sofast_station
    from glshade.twin.reconstruct import measure_facet

    d = _data()
    station = read_sofast_station(
        *(d / STATION_FILES[k] for k in ("camera", "display", "orientation", "facet"))
    )
    m = read_sofast_measurement(d / "measurement_facet.h5")
    c = read_sofast_calibration(d / STATION_FILES["calibration"])
    return measure_facet(station, m, c)


def test_the_real_facet_matches_sofasts_slopes_and_focal_lengths(measured) -> None:
    """glshade end to end (its decoder, its mask, corners and pose, its solver) against
    SOFAST's published slopes: within 0.05 mrad rms; focal lengths within 1 %."""
    sofast = _expected("CalculationImageProcessingFacet/mask_processed").astype(bool)
    ref = np.full((2, *sofast.shape), np.nan)
    ref[:, sofast] = _expected("SlopeSolverData/slopes_facet_xy")
    both = measured.mask & sofast
    assert both.sum() >= 0.99 * sofast.sum()
    diff = measured.slopes[:, both] - ref[:, both]
    rms = np.sqrt(np.mean(diff**2, axis=1))
    assert np.all(rms < 0.05e-3), rms  # measured: 0.0094, 0.0088 mrad
    surf = _expected("SlopeSolverData/surf_coefs_facet")
    ref_focal = 1 / (4 * surf[[2, 5]]) * 1000
    assert np.allclose(measured.focal_lengths_mm, ref_focal, rtol=0.01)  # measured: 0.08 %, 0.03 %
    assert measured.pose.reprojection_px < 0.5


def test_the_facet_corners_are_sofasts(measured) -> None:
    """The corners found agree with SOFAST's to a pixel, in its order."""
    ref = _expected("CalculationImageProcessingFacet/loop_facet_image_refine").T
    assert np.max(np.abs(measured.pose.corners_px - ref)) < 1.0
