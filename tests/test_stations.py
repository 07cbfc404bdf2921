"""Stations: the camera, the screen and the part posed in one world frame (docs/stations.md).

Oracles: the rig's closed forms (the preset and the same rig written as explicit poses
render the same bits), rigid motion (moving the whole station moves nothing in its
images), OpenCV's own conversions (``cv2.Rodrigues``, ``cv2.projectPoints``) and the NumPy
float64 oracle for layouts the rig cannot express (uv within the stated tolerance).
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from glshade.app.cli import main
from glshade.errors import SceneError
from glshade.oracle.renderer import OracleRenderer
from glshade.poses import Placement, look_at_axes, rotation_ypr, to_extrinsics
from glshade.scene import Scene, paper_scene

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
#: GL fp32 uv against the fp64 oracle (mm): the project's bound for any station.
UV_FP32_MM = 2e-3
#: GL fp64 uv against the oracle (mm) at 10 m.
UV_FP64_MM = 1e-9


@pytest.fixture(scope="module")
def oracle():
    with OracleRenderer() as renderer:
        yield renderer


def rig(surface: str = "sphere", theta: float = 45.0, azimuth: float = 0.0, size: int = 40):
    scene = paper_scene(surface, theta, 4.0, 0.005).with_size(size)
    return scene.updated(camera={"azimuth_deg": azimuth}, defect={"x0": 1.5, "z0": -2.0})


def explicit(scene: Scene) -> Scene:
    """``scene``'s rig written as explicit poses: a look-at camera at the rig's principal
    point and a placed screen at the rig's screen centre, both aimed at the origin."""
    station = scene.station
    return scene.updated(
        camera={"pose": "look_at", "position": [float(x) for x in station.camera.position]},
        emitter={"pose": "placed", "centre": [float(x) for x in station.screen.centre]},
    )


# --------------------------------------------------------------------------- the rig
@pytest.mark.parametrize("theta, azimuth", [(45.0, 0.0), (5.0, 30.0), (80.0, -120.0)])
@pytest.mark.parametrize("precision", ["fp32", "fp64"])
def test_the_rig_as_explicit_poses_renders_the_same_bits(renderer, theta, azimuth, precision):
    scene = rig("sphere", theta, azimuth).updated(render={"precision": precision})
    posed = explicit(scene)
    assert posed.camera.pose == "look_at" and posed.emitter.pose == "placed"
    a, b = renderer.render(scene, ("image", "uv")), renderer.render(posed, ("image", "uv"))
    assert np.array_equal(a.image, b.image)
    if precision == "fp32":
        assert np.array_equal(a.uv, b.uv, equal_nan=True)
    else:  # the last bit of a unit vector recomputed from a position written out
        assert np.nanmax(np.abs(a.uv - b.uv)) < 1e-11


@pytest.mark.gl
@pytest.mark.parametrize("method", ["paper", "pmd"])
def test_the_rig_as_explicit_poses_measures_the_same_json(tmp_path, capsys, method):
    scene = rig("flat", 30.0, size=64)
    answers = []
    for name, each in (("rig", scene), ("posed", explicit(scene))):
        path = tmp_path / f"{name}.toml"
        each.save(path)
        assert main(["measure", str(path), "--method", method, "--json"]) == 0
        answer = json.loads(capsys.readouterr().out)
        answers.append({k: v for k, v in answer.items() if k not in ("seconds", "scene")})
    assert answers[0] == answers[1]


def test_a_rig_scene_file_is_written_as_before():
    written = paper_scene("flat", 45.0, 4.0, 0.005).to_dict()
    assert "part" not in written and "calibration" not in written
    assert not {"pose", "look_at", "up", "yaw_deg"} & set(written["camera"])
    assert not {"pose", "centre", "look_at", "up", "roll_deg"} & set(written["emitter"])


def test_the_gaze_of_the_rig_is_its_own_numbers():
    scene = rig("flat", 30.0, 20.0)
    gaze = scene.gaze
    assert (gaze.theta_rad, gaze.azimuth_rad) == (scene.camera.theta_rad, scene.camera.azimuth_rad)
    assert (gaze.camera_mm, gaze.screen_mm) == (175.6, 256.0)
    posed = explicit(scene).gaze  # worked out from the poses: the same within rounding
    assert posed.theta_rad == pytest.approx(gaze.theta_rad, abs=1e-12)
    assert posed.azimuth_rad == pytest.approx(gaze.azimuth_rad, abs=1e-12)
    assert posed.camera_mm == pytest.approx(175.6, rel=1e-12)
    assert posed.screen_mm == pytest.approx(256.0, rel=1e-12)


# --------------------------------------------------------------------------- conventions
def test_look_at_axes_are_right_handed_and_aimed():
    axis, right, up, distance = look_at_axes(
        np.array([100.0, 50.0, 20.0]), np.array([0.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    )
    assert distance == pytest.approx(math.sqrt(100**2 + 50**2 + 20**2))
    np.testing.assert_allclose(axis, -np.array([100.0, 50.0, 20.0]) / distance)
    np.testing.assert_allclose(np.cross(right, up), -axis, atol=1e-15)  # the camera looks along -z
    assert right[1] == pytest.approx(0.0, abs=1e-15) and up[1] > 0.0


def test_turns_are_about_the_own_axes_in_yaw_pitch_roll_order():
    np.testing.assert_allclose(rotation_ypr(90.0, 0.0, 0.0) @ [0, 0, 1], [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(rotation_ypr(0.0, 90.0, 0.0) @ [0, 1, 0], [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(rotation_ypr(0.0, 0.0, 90.0) @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    # intrinsic: yaw first, then pitch about the yawed x axis
    expected = rotation_ypr(30.0, 0.0, 0.0) @ rotation_ypr(0.0, 20.0, 0.0)
    np.testing.assert_allclose(rotation_ypr(30.0, 20.0, 0.0), expected, atol=1e-15)
    assert rotation_ypr(0.0, 0.0, 0.0) is not None and (rotation_ypr(0, 0, 0) == np.eye(3)).all()


def test_a_camera_yaw_turns_its_view_left():
    scene = rig("flat", 45.0)
    turned = scene.updated(camera={"yaw_deg": 10.0})
    pose, base = turned.camera_pose(), scene.camera_pose()
    np.testing.assert_array_equal(pose.position, base.position)
    assert pose.forward @ base.right < 0.0  # towards its left
    assert math.degrees(math.acos(pose.forward @ base.forward)) == pytest.approx(10.0)


def test_opencv_extrinsics_give_the_look_at_pose_and_project_as_opencv_does():
    scene = rig("flat", 40.0, 25.0).updated(camera={"pose": "look_at"})
    pose = scene.camera_pose()
    rvec, tvec = to_extrinsics(pose.position, pose.forward, pose.right, pose.up)
    viaopencv = scene.updated(camera={"pose": "extrinsics", "rvec": list(rvec), "tvec": list(tvec)})
    other = viaopencv.camera_pose()
    for name in ("position", "forward", "right", "up"):
        np.testing.assert_allclose(getattr(other, name), getattr(pose, name), atol=1e-9)
    # the camera's pixel rays through world points land where cv2.projectPoints puts them
    cam = viaopencv.camera
    fx = cam.focal / cam.pixel_pitch
    k = np.array([[fx, 0, cam.width / 2 - 0.5], [0, fx, cam.height / 2 - 0.5], [0, 0, 1.0]])
    origin, rays = cam.pixel_rays(rows=slice(3, 4), cols=slice(7, 8), pose=other)
    point = origin + 150.0 * rays[0, 0]
    projected, _ = cv2.projectPoints(point[None], rvec, tvec, k, np.zeros(5))
    np.testing.assert_allclose(projected.ravel(), [7.0, 3.0], atol=1e-7)


def test_intrinsics_k_are_the_focal_and_pitch_they_describe(renderer):
    scene = rig("sphere", 45.0, size=32)
    cam = scene.camera
    fx = cam.focal / cam.pixel_pitch
    same = scene.updated(camera={"intrinsics": [fx, fx, cam.width / 2 - 0.5, cam.height / 2 - 0.5]})
    a, b = renderer.render(scene, ("uv",)), renderer.render(same, ("uv",))
    assert np.nanmax(np.abs(a.uv - b.uv)) < 1e-3
    # a principal point moved by 4 px along x shows the picture moved by 4 px
    shifted = scene.updated(
        camera={"intrinsics": [fx, fx, cam.width / 2 - 0.5 + 4, cam.height / 2 - 0.5]}
    )
    c = renderer.render(shifted, ("uv",)).uv
    assert np.nanmax(np.abs(c[:, 4:] - a.uv[:, :-4])) < 1e-3


def test_a_mode_key_of_another_mode_is_refused_in_one_line():
    with pytest.raises(SceneError, match=r'camera.pose: must be "look_at" where camera.position'):
        Scene().updated(camera={"position": [0.0, 100.0, 100.0]})
    with pytest.raises(SceneError, match=r"camera.rvec: must be a list of 3"):
        Scene().updated(camera={"pose": "extrinsics"})
    with pytest.raises(SceneError, match=r"camera.up: .*parallel"):  # looking straight down
        Scene().updated(camera={"pose": "look_at", "position": [0.0, 100.0, 0.0]})
    with pytest.raises(SceneError, match=r"camera.position: .*coincide"):
        Scene().updated(camera={"pose": "look_at", "position": [0.0, 0.0, 0.0]})
    with pytest.raises(SceneError, match=r"camera.up: .*parallel"):
        Scene().updated(camera={"pose": "look_at", "up": [0.0, 0.0, 0.0]})
    with pytest.raises(SceneError, match=r"emitter.up: .*parallel"):
        Scene().updated(emitter={"pose": "placed", "up": [0.0, 0.0, 0.0]}).emitter_plane()


def test_a_vector_component_is_a_path_of_its_own():
    scene = Scene().updated(camera={"pose": "look_at", "position": [0.0, 100.0, 100.0]})
    moved = scene.with_value("camera.position[1]", "120 mm")
    assert (
        moved.camera.position == (0.0, 120.0, 100.0) and moved.value("camera.position[1]") == 120.0
    )
    with pytest.raises(SceneError, match=r"camera.position\[3\]: must be camera.position\[0\] to"):
        scene.with_value("camera.position[3]", 1.0)
    with pytest.raises(SceneError, match=r"camera.focal\[0\]"):
        scene.with_value("camera.focal[0]", 1.0)


# --------------------------------------------------------------------------- rigid motion
def moved_station(scene: Scene, position, yaw, pitch, roll) -> Scene:
    """``scene`` with its whole station (camera, screen, part) moved by one rigid motion."""
    motion = Placement(np.asarray(position, float), rotation_ypr(yaw, pitch, roll))
    station = scene.station
    cam, screen = station.camera, station.screen
    return scene.updated(
        part={"position": list(position), "yaw_deg": yaw, "pitch_deg": pitch, "roll_deg": roll},
        camera={
            "pose": "look_at",
            "position": list(motion.to_world_points(cam.position)),
            "look_at": list(motion.to_world_points(cam.target)),
            "up": list(motion.to_world_vectors(cam.up)),
        },
        emitter={
            "pose": "placed",
            "centre": list(motion.to_world_points(screen.centre)),
            "look_at": list(motion.to_world_points(screen.centre + screen.normal)),
            "up": list(motion.to_world_vectors(screen.e_v)),
        },
    )


@pytest.mark.parametrize("precision", ["fp32", "fp64"])
def test_moving_the_whole_station_moves_nothing_in_its_pictures(renderer, precision):
    scene = rig("sphere", 35.0, 15.0).updated(render={"precision": precision})
    moved = moved_station(scene, [250.0, -40.0, 900.0], 33.0, -12.0, 7.0)
    a, b = renderer.render(scene, ("image", "uv")), renderer.render(moved, ("image", "uv"))
    seen = np.isfinite(a.uv[..., 0]) & np.isfinite(b.uv[..., 0])
    assert seen.mean() > 0.4 and np.array_equal(np.isnan(a.uv), np.isnan(b.uv))
    assert np.abs(a.uv - b.uv)[seen].max() < (UV_FP32_MM if precision == "fp32" else 1e-9)


def test_a_turned_part_moves_its_dent_in_the_world():
    scene = rig("flat", 45.0).updated(part={"position": [10.0, 0.0, 0.0], "yaw_deg": 90.0})
    part = scene.station.part
    np.testing.assert_allclose(
        part.to_world_points(np.array([1.0, 0.0, 0.0])), [10, 0, -1], atol=1e-12
    )
    local = scene.camera_pose()  # the camera seen from the part: moved and turned back
    np.testing.assert_allclose(local.position, part.to_local_points(scene.station.camera.position))


# --------------------------------------------------------------------------- other layouts
def overhead(precision: str, size: int = 40) -> Scene:
    """A screen overhead, facing down, with the camera off its mirror plane: a layout the
    rig cannot express."""
    return rig("sphere", 45.0, size=size).updated(
        camera={"pose": "look_at", "position": [60.0, 140.0, 110.0], "look_at": [0.0, 0.0, 0.0]},
        emitter={"pose": "placed", "centre": [-40.0, 300.0, -120.0], "look_at": [0.0, 0.0, 0.0]},
        render={"precision": precision},
    )


def sofast(precision: str, size: int = 40) -> Scene:
    """The SOFAST-like station of examples/: a camera beside a screen of 8.7 m x 3.5 m, 10 m
    above a large concave facet at near-normal incidence."""
    scene = Scene.load(EXAMPLES / "sofast_like_station.toml")
    return scene.updated(render={"precision": precision}).with_size(size)


@pytest.mark.parametrize("build", [overhead, sofast], ids=["overhead", "sofast"])
@pytest.mark.parametrize("precision", ["fp32", "fp64"])
def test_layouts_the_rig_cannot_express_render_as_the_oracle(renderer, oracle, build, precision):
    scene = build(precision)
    gl, ours = renderer.render(scene, ("uv", "mask")), oracle.render(scene, ("uv", "mask"))
    assert np.array_equal(gl.mask, ours.mask) and gl.mask.mean() > 0.3
    tolerance = UV_FP32_MM if precision == "fp32" else UV_FP64_MM
    assert np.abs(gl.uv - ours.uv)[gl.mask].max() < tolerance


def test_the_sofast_station_is_seen_at_near_normal_incidence():
    gaze = sofast("fp32").gaze
    assert 85.0 < math.degrees(gaze.theta_rad) < 89.0
    assert gaze.camera_mm == pytest.approx(10018.0, rel=1e-4)


# --------------------------------------------------------------------------- the viewer
def test_a_drag_orbits_a_look_at_camera_about_its_aim_point():
    from glshade.rig import orbit_position

    target = np.array([5.0, 1.0, -3.0])
    position = target + 100.0 * np.array([0.0, math.sin(0.5), math.cos(0.5)])
    np.testing.assert_allclose(orbit_position(position, target, 0.0, 0.0), position, atol=1e-12)
    raised = orbit_position(position, target, 0.0, -40.0)  # up: 10 degrees higher
    assert np.linalg.norm(raised - target) == pytest.approx(100.0)
    assert math.degrees(math.asin((raised - target)[1] / 100.0)) == pytest.approx(
        math.degrees(0.5) + 10.0
    )
    turned = orbit_position(position, target, 40.0, 0.0)  # right: the azimuth turns +10
    assert math.degrees(math.atan2(*(turned - target)[[0, 2]])) == pytest.approx(10.0)


# --------------------------------------------------------------------------- sweeps, optimiser
@pytest.mark.gl
def test_a_posed_station_sweeps_over_a_position_component_and_a_yaw(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["sweep", str(EXAMPLES / "overhead_sweep.toml"), "--out", str(out)]) == 0
    rows = list(csv.DictReader((out / "results.csv").open()))
    assert [(r["camera.position[1]"], r["camera.yaw_deg"]) for r in rows][:4] == [
        ("120.0", "-2.0"), ("120.0", "0.0"), ("120.0", "2.0"), ("140.0", "-2.0"),
    ]  # fmt: skip
    measured = [r for r in rows if r["status"] == "ok"]
    assert len(measured) >= 6
    assert all(float(r["pmd_depth_um"]) == pytest.approx(5.0, rel=0.05) for r in measured)
    # the station measures what its layout shows: raising the camera shrinks the shift
    shift = {
        r["camera.position[1]"]: float(r["pmd_shift_mm"])
        for r in rows
        if r["camera.yaw_deg"] == "0.0"
    }
    assert shift["120.0"] > shift["140.0"] > shift["160.0"]
    capsys.readouterr()


@pytest.mark.gl
def test_the_optimiser_moves_a_posed_camera(tmp_path, capsys):
    argv = [
        "optimize", str(EXAMPLES / "overhead_station.toml"), "--over",
        "camera.position[1]=110..200", "--metric", "continuous", "--grid", "3", "--refine", "3",
        "--size", "48", "--json", "--yes",
    ]  # fmt: skip
    assert main(argv) == 0
    answer = json.loads(capsys.readouterr().out)
    assert 110.0 <= answer["optimum"]["camera.position[1]"] <= 200.0


@pytest.mark.gl
@pytest.mark.parametrize("method, precision", [("paper", "fp32"), ("pmd", "fp32"), ("pmd", "fp64")])
def test_the_sofast_station_measures_with_both_instruments(capsys, method, precision):
    argv = ["measure", str(EXAMPLES / "sofast_like_station.toml"), "--method", method,
            "--size", "96", "--precision", precision, "--json"]  # fmt: skip
    if method == "paper":  # stripes a metre apart, seen in steps of 25 mm
        argv += ["--emitter", "stripes", "--period", "1000", "--step", "25"]
    assert main(argv) == 0
    answer = json.loads(capsys.readouterr().out)
    assert answer["status"] == "ok"
    if method == "pmd":  # the dent's steepest slope, dmax e^-1/2 / sigma = 607 urad
        assert answer["pmd_slope_urad"] == pytest.approx(607.0, rel=0.05)
        assert answer["pmd_depth_um"] == pytest.approx(50.0, rel=0.1)
    else:  # the stripes' shift as the closed form reads the station's gaze geometry
        assert answer["deflection_px"] == pytest.approx(answer["deflection_law_px"], rel=0.15)


# --------------------------------------------------------------------------- refusals
@pytest.mark.parametrize(
    "emitter, words",
    [
        ({"pose": "placed", "centre": [0.0, 181.0, -181.0], "look_at": [0.0, 400.0, -400.0]},
         "the screen is seen from behind"),
        ({"pose": "placed", "centre": [0.0, 181.0, 400.0]}, "no camera pixel sees the screen"),
    ],
    ids=["behind", "unseen"],
)  # fmt: skip
def test_a_station_that_shows_no_screen_is_refused_in_one_line(tmp_path, capsys, emitter, words):
    scene = Scene().updated(camera={"pose": "look_at"}, emitter=emitter).with_size(32)
    scene.save(tmp_path / "station.toml")
    (tmp_path / "sweep.toml").write_text(
        'base = "station.toml"\nsize = 32\n[grid]\n"camera.focal" = [25.0, 26.0]\n'
    )
    for argv in (
        ["measure", str(tmp_path / "station.toml"), "--json"],
        ["sweep", str(tmp_path / "sweep.toml"), "--out", str(tmp_path / "out")],
    ):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and words in err[0], err
    assert not (tmp_path / "out").exists()
