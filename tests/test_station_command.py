"""``glshade station``: the station's numbers against closed forms (the paper's rig, a flat
mirror seen by a look-at camera with a placed screen), its picture, and its refusals."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from glshade.app.cli import main
from glshade.errors import GlshadeError
from glshade.oracle.station_report import SCREEN_MM, SCREEN_PIXELS, sensor_slice, station_report
from glshade.scene import Scene

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def flat_station(
    tmp_path,
    elevation_deg: float = 30.0,
    camera_mm: float = 200.0,
    screen_mm: float = 300.0,
    azimuth_deg: float = 0.0,
    extra: str = "",
):
    """A scene file: a flat mirror, a look-at camera ``camera_mm`` from the origin at
    ``elevation_deg`` and a placed screen ``screen_mm`` from it on the reflected line of
    sight, facing it, both turned ``azimuth_deg`` about +y; a 64 x 48 sensor of 0.08 mm
    pixels behind a 25 mm lens."""
    t, a = math.radians(elevation_deg), math.radians(azimuth_deg)
    camera = camera_mm * np.array(
        [math.sin(a) * math.cos(t), math.sin(t), math.cos(a) * math.cos(t)]
    )
    screen = screen_mm * np.array(
        [-math.sin(a) * math.cos(t), math.sin(t), -math.cos(a) * math.cos(t)]
    )
    path = tmp_path / "flat.toml"
    path.write_text(
        f"""[surface]
kind = "flat"

[camera]
pose = "look_at"
position = [{", ".join(repr(float(c)) for c in camera)}]
width = 64
height = 48
pixel_pitch = 0.08
focal = 25.0

[emitter]
pose = "placed"
centre = [{", ".join(repr(float(c)) for c in screen)}]
{extra}
""",
        encoding="utf-8",
    )
    return path


def test_the_paper_rig_in_closed_form():
    scene = Scene().with_size(64)  # 64 pixels of 0.08 mm: the paper's field of view
    report = station_report(scene)
    assert report.working_distance_mm == pytest.approx(175.6, abs=1e-9)
    assert report.aim_distance_mm == pytest.approx(175.6, abs=1e-9)
    assert report.incidence_deg == pytest.approx(45.0, abs=1e-9)
    assert report.elevation_deg == pytest.approx(45.0, abs=1e-9)
    assert report.screen_distance_mm == pytest.approx(256.0, abs=1e-9)
    assert report.chief_on_screen
    assert report.chief_uv_mm == pytest.approx((0.0, 0.0), abs=1e-6)
    # the screen stands square to the reflected chief ray: the mirror image of the sensor
    # plane is parallel to it, so screen points move linearly with sensor points, by the
    # unfolded distance over the focal length
    unfolded = 175.6 + 256.0
    assert report.coverage == 1.0
    assert report.sampling_unit == SCREEN_MM
    assert report.sampling == pytest.approx((unfolded * 0.08 / 25.0,) * 2, rel=1e-9)
    edge = unfolded * 31.5 * 0.08 / 25.0  # the outermost pixel centres, 31.5 pixels off axis
    assert report.u_range_mm == pytest.approx((-edge, edge), abs=1e-9)
    assert report.v_range_mm == pytest.approx((-edge, edge), abs=1e-9)
    assert report.u_share == pytest.approx(2 * edge / 300.0, rel=1e-12)


@pytest.mark.parametrize("azimuth_deg", [0.0, 30.0])
def test_a_flat_mirror_with_a_look_at_camera_and_a_placed_screen(tmp_path, azimuth_deg):
    scene = Scene.load(flat_station(tmp_path, azimuth_deg=azimuth_deg))
    report = station_report(scene)
    assert report.working_distance_mm == pytest.approx(200.0, abs=1e-9)
    assert report.aim_distance_mm == pytest.approx(200.0, abs=1e-9)
    assert report.incidence_deg == pytest.approx(60.0, abs=1e-9)  # 90 - elevation
    assert report.elevation_deg == pytest.approx(30.0, abs=1e-9)
    assert report.normal_world == pytest.approx((0.0, 1.0, 0.0), abs=1e-15)
    assert report.screen_distance_mm == pytest.approx(300.0, abs=1e-9)
    assert report.chief_uv_mm == pytest.approx((0.0, 0.0), abs=1e-6)
    assert report.dent_pixel == pytest.approx((23.5, 31.5), abs=1e-9)
    # unfolded: 200 + 300 mm from the camera's mirror image to a screen parallel to its
    # mirrored sensor; pixel centres 31.5 (x) and 23.5 (y) pixels off axis at the edges
    assert report.grid == (48, 64)
    assert report.coverage == 1.0
    assert report.sampling == pytest.approx((500.0 * 0.08 / 25.0,) * 2, rel=1e-9)
    u_edge, v_edge = 500.0 * 31.5 * 0.08 / 25.0, 500.0 * 23.5 * 0.08 / 25.0
    assert report.u_range_mm == pytest.approx((-u_edge, u_edge), abs=1e-9)
    assert report.v_range_mm == pytest.approx((-v_edge, v_edge), abs=1e-9)
    assert report.v_share == pytest.approx(2 * v_edge / 300.0, rel=1e-12)


def test_a_pixelated_fringe_screen_is_sampled_in_its_pixels(tmp_path):
    extra = 'kind = "fringes"\npixel_pitch = 0.2'
    report = station_report(Scene.load(flat_station(tmp_path, extra=extra)))
    assert report.sampling_unit == SCREEN_PIXELS
    assert report.sampling == pytest.approx((1.6 / 0.2,) * 2, rel=1e-9)


def test_a_dent_outside_the_image_has_no_sampling(tmp_path):
    scene = Scene.load(flat_station(tmp_path)).with_value("defect.x0", 500.0)
    report = station_report(scene)
    assert report.sampling is None and "outside the image" in report.sampling_note
    assert not report.chief_on_screen


def test_the_grid_spreads_over_the_sensor():
    assert len(range(1024)[sensor_slice(1024, 64)]) == 64
    assert range(1024)[sensor_slice(1024, 64)][0] == 7
    assert list(range(48)[sensor_slice(48, 64)]) == list(range(48))
    assert len(range(100)[sensor_slice(100, 64)]) == 50


def test_the_command_prints_the_numbers_and_writes_the_picture(tmp_path, capsys):
    out = tmp_path / "station.png"
    assert main(["station", str(flat_station(tmp_path)), "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert out.read_bytes().startswith(PNG_SIGNATURE) and out.stat().st_size > 10_000
    lines = [line for line in printed.splitlines() if line.startswith("  ")]
    assert len(lines) == 10
    assert all(("mm" in line or "deg" in line or "%" in line) for line in lines)
    assert "working distance     200.000 mm" in printed
    assert f"wrote {out}" in printed


def test_the_command_prints_json(tmp_path, capsys):
    out = tmp_path / "station.png"
    assert main(["station", str(flat_station(tmp_path)), "-o", str(out), "--json"]) == 0
    numbers = json.loads(capsys.readouterr().out)
    assert numbers["working_distance_mm"] == pytest.approx(200.0, abs=1e-9)
    assert numbers["incidence_deg"] == pytest.approx(60.0, abs=1e-9)
    assert numbers["chief_ray_on_screen"] is True
    assert numbers["sampling_unit"] == SCREEN_MM
    assert out.read_bytes().startswith(PNG_SIGNATURE)


def _refused(tmp_path, capsys, argv):
    """Run ``argv``; its exit code, its stderr lines (stdout must be empty)."""
    code = main(argv)
    captured = capsys.readouterr()
    assert captured.out == ""
    return code, captured.err.splitlines()


def test_a_screen_facing_away_from_the_part_is_refused(tmp_path, capsys):
    # the paper's mirror position, but facing away: the part shows the camera its back
    scene = flat_station(tmp_path, extra="look_at = [0.0, 300.0, -520.0]")
    out = tmp_path / "station.png"
    code, err = _refused(tmp_path, capsys, ["station", str(scene), "-o", str(out)])
    assert code == 2 and len(err) == 1
    assert err[0].startswith("glshade: error: station: the screen is seen from behind")
    assert "emitter.pose = placed" in err[0]
    assert not out.exists()
    with pytest.raises(GlshadeError, match="seen from behind"):
        station_report(Scene.load(scene))


def test_a_screen_behind_the_camera_is_refused(tmp_path, capsys):
    path = flat_station(tmp_path)
    scene = Scene.load(path).with_values(
        [("emitter.centre", (0.0, 200.0, 346.0)), ("emitter.look_at", (0.0, 400.0, 692.0))]
    )
    scene.save(path)
    out = tmp_path / "station.png"
    code, err = _refused(tmp_path, capsys, ["station", str(path), "-o", str(out)])
    assert code == 2 and len(err) == 1
    assert err[0].startswith("glshade: error: station: no camera pixel sees the screen")
    assert not out.exists()


def test_an_output_directory_is_refused(tmp_path, capsys):
    code, err = _refused(tmp_path, capsys, ["station", "-o", str(tmp_path)])
    assert code == 2 and len(err) == 1
    assert (
        err[0]
        == f"glshade: error: -o {tmp_path}: is a directory; glshade only writes regular files"
    )


def test_a_picture_must_be_a_png(tmp_path, capsys):
    code, err = _refused(tmp_path, capsys, ["station", "-o", str(tmp_path / "s.jpg")])
    assert code == 2 and len(err) == 1 and "-o" in err[0]
    assert not (tmp_path / "s.jpg").exists()
