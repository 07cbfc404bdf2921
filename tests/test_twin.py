"""The twin's reconstruction: SOFAST's slope solver reproduced (on SOFAST's own inputs
and on a parabola whose slopes are known by construction), and the whole real
measurement reconstructed by glshade against SOFAST's published results."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from glshade.twin.slopes import SlopeInputs, solve

pytest.importorskip("h5py")


@pytest.fixture(scope="module")
def expected(sofast_dir: Path):
    """A dataset of SOFAST's own results on the measurement (expected_facet.h5)."""
    import h5py

    def read(key: str) -> np.ndarray:
        with h5py.File(sofast_dir / "expected_facet.h5", "r") as h5:
            return np.asarray(h5["DataSofastCalculation/facet/facet_000/" + key][()])

    return read


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


def test_the_solver_reproduces_sofast_on_its_inputs(expected) -> None:
    """Fed SOFAST's own geometry (expected_facet.h5), the solver returns SOFAST's slopes
    and surface to round-off."""
    import cv2

    geo = "CalculationDataGeometryFacet/"
    rot = cv2.Rodrigues(expected(geo + "SpatialOrientation/r_cam_optic").reshape(3, 1))[0]
    cam_optic = 1000 * expected(geo + "SpatialOrientation/v_cam_optic_cam").ravel()
    cam_screen = 1000 * expected(geo + "SpatialOrientation/v_cam_screen_cam").ravel()
    camera = -rot @ cam_optic
    inputs = SlopeInputs(
        rays=expected(geo + "u_pixel_pointing_facet").T,
        screen_mm=1000 * expected(geo + "v_screen_points_facet").T,
        camera_mm=camera,
        screen_origin_mm=camera + rot @ cam_screen,
        measure_ray=expected(geo + "u_cam_measure_point_facet").ravel(),
        align_mm=np.zeros(3),
        distance_mm=1000 * float(expected(geo + "measure_point_screen_distance")),
        focal_mm=(100_000.0, 100_000.0),
    )
    sol = solve(inputs)
    assert np.max(np.abs(sol.slopes - expected("SlopeSolverData/slopes_facet_xy"))) < 1e-12
    surf = expected("SlopeSolverData/surf_coefs_facet")
    assert np.allclose(sol.surface[[2, 4, 5]] * 1000, surf[[2, 4, 5]], rtol=1e-9)
    assert np.allclose(
        sol.alignment[:3, :3], expected("SlopeSolverData/trans_alignment")[:3, :3], atol=1e-12
    )


@pytest.fixture(scope="module")
def measured(sofast_dir):
    from glshade.capture.sofast import read_sofast_calibration, read_sofast_measurement
    from glshade.capture.sofast_station import STATION_FILES, read_sofast_station
    from glshade.twin.reconstruct import measure_facet

    d = sofast_dir
    station = read_sofast_station(
        *(d / STATION_FILES[k] for k in ("camera", "display", "orientation", "facet"))
    )
    m = read_sofast_measurement(d / "measurement_facet.h5")
    c = read_sofast_calibration(d / STATION_FILES["calibration"])
    return measure_facet(station, m, c)


def test_the_real_facet_matches_sofasts_slopes_and_focal_lengths(measured, expected) -> None:
    """glshade end to end (its decoder, its mask, corners and pose, its solver) against
    SOFAST's published slopes: within 0.05 mrad rms; focal lengths within 1 %."""
    sofast = expected("CalculationImageProcessingFacet/mask_processed").astype(bool)
    ref = np.full((2, *sofast.shape), np.nan)
    ref[:, sofast] = expected("SlopeSolverData/slopes_facet_xy")
    both = measured.mask & sofast
    assert both.sum() >= 0.99 * sofast.sum()
    diff = measured.slopes[:, both] - ref[:, both]
    rms = np.sqrt(np.mean(diff**2, axis=1))
    assert np.all(rms < 0.05e-3), rms  # measured: 0.0065, 0.0089 mrad
    surf = expected("SlopeSolverData/surf_coefs_facet")
    ref_focal = 1 / (4 * surf[[2, 5]]) * 1000
    assert np.allclose(measured.focal_lengths_mm, ref_focal, rtol=0.01)  # measured: 0.12 %, 0.01 %
    assert measured.pose.reprojection_px < 0.5


def test_the_facet_corners_are_sofasts(measured, expected) -> None:
    """The corners found agree with SOFAST's to a pixel, in its order."""
    ref = expected("CalculationImageProcessingFacet/loop_facet_image_refine").T
    assert np.max(np.abs(measured.pose.corners_px - ref)) < 1.0


def test_the_twin_renders_where_an_fp64_trace_of_its_station_lands(
    measured, renderer, sofast_dir
) -> None:
    """The twin scene (camera by OpenCV extrinsics, intrinsics and distortion; the placed
    screen; the nominal parabola in the aligned facet frame) rendered by glshade puts each
    facet pixel's screen point where a float64 trace of the station's own geometry does:
    the camera's undistorted ray, the parabola, the mirror reflection, the screen plane."""
    from glshade.capture.sofast import read_sofast_measurement
    from glshade.capture.sofast_station import STATION_FILES, read_sofast_station
    from glshade.scene import Scene
    from glshade.twin.compare import twin_screen_points
    from glshade.twin.scene import FACET_TO_PART, twin_frames, twin_scene_dict
    from glshade.twin.slopes import intersect

    d = sofast_dir
    station = read_sofast_station(
        *(d / STATION_FILES[k] for k in ("camera", "display", "orientation", "facet"))
    )
    m = read_sofast_measurement(d / "measurement_facet.h5")
    scene = Scene.from_dict(twin_scene_dict(station, m, measured, "nominal", direction="u"))
    uv = renderer.render(scene, ("uv",)).output("uv").astype(np.float64)
    frames = twin_frames(station, measured)
    rendered = twin_screen_points(uv, scene.emitter_plane(), frames)[measured.mask]
    # the fp64 trace, in the aligned facet frame
    cam_rot, cam_t = frames.camera_from_part
    to_facet = FACET_TO_PART.T
    rows, cols = np.nonzero(measured.mask)
    rays = station.camera.rays(cols, rows) @ cam_rot @ FACET_TO_PART  # camera -> part -> facet
    camera = to_facet @ (-cam_rot.T @ cam_t)
    f = 100_000.0
    points = intersect(np.array([0.0, 0.0, 1 / (4 * f), 0.0, 0.0, 1 / (4 * f)]), rays, camera)
    normal = np.stack([-points[:, 0] / (2 * f), -points[:, 1] / (2 * f), np.ones(len(points))], 1)
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    out = rays - 2 * (rays * normal).sum(1, keepdims=True) * normal
    part_rot, part_t = frames.part_from_screen
    screen_normal = to_facet @ part_rot[:, 2]
    screen_origin = to_facet @ part_t
    along = ((screen_origin - points) @ screen_normal) / (out @ screen_normal)
    traced = frames.screen_of_part((points + out * along[:, None]) @ FACET_TO_PART.T)
    err = np.linalg.norm(rendered[:, :2] - traced[:, :2], axis=1)
    assert np.all(np.isfinite(err))
    assert np.max(err) < 0.02, np.max(err)  # mm, 10 m away; measured 0.0019 max, 0.0005 rms


@pytest.mark.gl
def test_the_twin_command_writes_its_outputs(tmp_path, capsys, sofast_dir) -> None:
    import json

    from glshade.app.cli import main

    out = tmp_path / "twin"
    args = [
        "twin",
        str(sofast_dir / "measurement_facet.h5"),
        "--out",
        str(out),
        "--supersample",
        "1",
    ]
    assert main(args) == 0
    names = {p.name for p in out.iterdir()}
    assert {
        "twin.npz",
        "twin_x.toml",
        "twin_y.toml",
        "slopes.png",
        "deviation.png",
        "frames.png",
    } <= names
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "ok" and summary["status_reason"] == ""
    assert "Status: **ok**" in (out / "summary.md").read_text()
    assert summary["pixels"] >= 7000
    assert (
        abs(summary["focal_lengths_m"][0] - 120.0) < 1.2
        and abs(summary["focal_lengths_m"][1] - 108.9) < 1.1
    )
    # the part's waviness: SOFAST's own slopes less its fitted planes are 0.46, 0.57 mrad rms
    assert np.allclose(summary["slope_rms_from_fit_mrad"], (0.46, 0.57), atol=0.03)
    rows = summary["frames"]["x"]["periods"]
    real = [r["real_modulation_share"] for r in rows]
    assert real[-1] < real[0]  # the finest fringe is blurred in the real frames
    assert all(abs(r["twin_modulation_share"] - 0.5) < 0.02 for r in rows)
    # closed loop: the twin's frames, decoded and solved like the real ones, give back the
    # nominal facet (measured: 100.00 m, 100.00 m; 0.003, 0.001 mrad rms)
    loop = summary["twin_reconstructed"]
    assert np.allclose(loop["focal_lengths_m"], (100.0, 100.0), rtol=1e-3)
    assert max(loop["slope_error_rms_mrad"]) < 0.01 and max(loop["slope_error_max_mrad"]) < 0.03
    maps = np.load(out / "twin.npz")
    assert np.isfinite(maps["screen_deviation_mm"][:, maps["mask"]]).all()
    from_twin = maps["deviation_from_twin"][:, maps["mask"]]
    assert np.isfinite(from_twin).mean() > 0.99
    rms = np.sqrt(np.nanmean(from_twin**2, axis=1)) * 1e3
    assert np.allclose(rms, summary["slope_rms_from_twin_mrad"], rtol=1e-9)


def test_the_twin_command_refuses_bad_input(tmp_path, capsys, sofast_dir) -> None:
    from glshade.app.cli import main

    out = tmp_path / "o"
    meas = str(sofast_dir / "measurement_facet.h5")
    lines = [
        [str(tmp_path / "missing.h5"), "--station", str(sofast_dir)],
        [meas, "--station", str(tmp_path)],
        [meas, "--focal", "0", "100"],
        [meas, "--supersample", "0"],
    ]
    for line in lines:
        assert main(["twin", *line, "--out", str(out)]) == 2, line
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 4 and all(line.startswith("glshade: error:") for line in err), err
    assert "missing.h5" in err[0] and "camera_sofast_downsampled.h5" in err[1]
    assert "--focal" in err[2] and "--supersample 0" in err[3] and "1 to 16" in err[3]
    assert not out.exists()


def test_the_twins_frames_are_the_stations_frame_for_frame(measured, renderer, sofast_dir) -> None:
    """Rendered with SOFAST's periods and its phase origins (x from the screen's low
    edge, y from its high edge), the twin's coarsest fringe has the real one's phase
    where the facet's shape cannot move it (a 9.7 m period along x, 3.9 m along y)."""
    from glshade.capture.sofast import read_sofast_measurement
    from glshade.capture.sofast_station import STATION_FILES, read_sofast_station
    from glshade.twin.run import run_twin

    d = sofast_dir
    station = read_sofast_station(
        *(d / STATION_FILES[k] for k in ("camera", "display", "orientation", "facet"))
    )
    m = read_sofast_measurement(d / "measurement_facet.h5")
    run = run_twin(station, m, None, renderer)
    mask = run.measured.mask
    for direction, limit in (("x", 0.03), ("y", 0.05)):  # measured: 0.012, 0.025 rad rms
        phases = []
        for frames in (run.real_frames[direction], run.twin_radiance[direction]):
            steps = 2 * np.pi * np.arange(frames.shape[1]) / frames.shape[1]
            sin = (frames[0] * np.sin(steps)[:, None, None]).sum(0)
            cos = (frames[0] * np.cos(steps)[:, None, None]).sum(0)
            phases.append(np.arctan2(sin, cos)[mask])
        diff = np.angle(np.exp(1j * (phases[0] - phases[1])))
        assert np.sqrt(np.mean(diff**2)) < limit, (direction, np.sqrt(np.mean(diff**2)))


def test_the_twin_command_reconstructs_without_rendering(tmp_path, sofast_dir) -> None:
    """--no-render --raw: the facet from the raw frames, no twin; its numbers say so."""
    import json

    from glshade.app.cli import main

    out = tmp_path / "t"
    args = ["twin", str(sofast_dir / "measurement_facet.h5"), "--out", str(out), "--no-render"]
    assert main([*args, "--raw"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["twin_reconstructed"] is None and summary["frames"] is None
    assert summary["status"] == "unchecked" and "not checked" in summary["status_reason"]
    assert summary["screen_deviation_rms_mm"] is None and summary["calibration"] is None
    assert np.allclose(summary["focal_lengths_m"], (119.89, 108.90), atol=0.05)  # raw frames
    assert not (out / "frames.png").exists() and (out / "deviation.png").exists()
    assert "decoded and solved alike" not in (out / "summary.md").read_text()


def test_a_fitted_twin_gives_back_the_fitted_facet(measured, renderer, sofast_dir) -> None:
    """--surface fitted: the twin carries the fitted parabola (tilt and twist terms kept);
    its frames decoded and solved alike return the real facet's focal lengths (measured:
    119.868 m, 108.894 m against 119.869 m, 108.894 m)."""
    from glshade.capture.sofast import read_sofast_calibration, read_sofast_measurement
    from glshade.capture.sofast_station import STATION_FILES, read_sofast_station
    from glshade.twin.run import run_twin

    station = read_sofast_station(
        *(sofast_dir / STATION_FILES[k] for k in ("camera", "display", "orientation", "facet"))
    )
    m = read_sofast_measurement(sofast_dir / "measurement_facet.h5")
    c = read_sofast_calibration(sofast_dir / STATION_FILES["calibration"])
    run = run_twin(station, m, c, renderer, surface="fitted")
    loop = run.summary["twin_reconstructed"]
    real = np.array(run.summary["focal_lengths_m"])
    assert np.allclose(loop["focal_lengths_m"], real, rtol=3e-4), (loop, real)
    assert max(loop["slope_error_rms_mrad"]) < 0.01


def test_the_twins_status_names_what_fails() -> None:
    from glshade.twin.run import trust

    loop = {"slope_error_rms_mrad": [0.002, 0.3]}
    assert trust({"reprojection_px": 0.2, "twin_reconstructed": loop})[0] == "unreliable"
    status, reason = trust({"reprojection_px": 1.7, "twin_reconstructed": None})
    assert status == "unreliable" and "1.70 px" in reason
    assert trust(
        {"reprojection_px": 0.2, "twin_reconstructed": {"slope_error_rms_mrad": [0.01]}}
    ) == ("ok", "")
