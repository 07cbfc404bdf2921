"""The scene a command line describes: ``--size`` against camera values typed beside it,
and one set of short names (``theta``) for every command's ``--set``."""

from __future__ import annotations

import subprocess
import sys

import pytest

from glshade.app.args import scene_from_args, setting_param, short_names
from glshade.app.cli import build_parser, main
from glshade.app.commands.view import VIEW_SIZE
from glshade.app.viewer.controls import by_name, controls, parse_sets
from glshade.errors import GlshadeError
from glshade.scene import Scene, paper_scene

SPHERE = """
[surface]
kind = "sphere"
radius = 70.0

[camera]
theta_deg = 30.0
width = 256
height = 256
pixel_pitch = 0.01
"""


def parsed(*argv: str) -> Scene:
    """The scene ``glshade measure ARGV`` would measure (parsed, not measured)."""
    return scene_from_args(build_parser("measure").parse_args(["measure", *argv]))


def test_a_typed_pixel_pitch_survives_size(tmp_path):
    path = tmp_path / "sphere.toml"
    path.write_text(SPHERE, encoding="utf-8")
    from_file = parsed(str(path))
    typed = ("--surface", "sphere", "--radius", "70", "--theta", "30")
    # the same scene as flags: --size sets the pixels, the typed pitch is kept
    assert parsed(*typed, "--set", "camera.pixel_pitch=0.01", "--size", "256") == from_file
    assert parsed(*typed, "--size", "256", "--set", "camera.pixel_pitch=10um") == from_file
    # the whole camera typed, --size agreeing with it
    whole = ("--set", "camera.width=256", "--set", "camera.height=256")
    assert parsed(*typed, *whole, "--set", "camera.pixel_pitch=0.01") == from_file
    assert parsed(*typed, *whole, "--set", "camera.pixel_pitch=0.01", "--size", "256") == (
        from_file
    )
    # a typed height is kept; the width is --size's, the file's field of view across
    tall = parsed(*typed, "--set", "camera.height=100", "--size", "512")
    assert (tall.camera.width, tall.camera.height) == (512, 100)
    assert tall.camera.pixel_pitch == pytest.approx(0.005 * 1024 / 512)


def test_size_keeps_a_files_field_of_view(tmp_path):
    path = tmp_path / "sphere.toml"
    path.write_text(SPHERE, encoding="utf-8")
    resized = parsed(str(path), "--size", "128")
    assert (resized.camera.width, resized.camera.height) == (128, 128)
    assert resized.camera.pixel_pitch == pytest.approx(0.02)  # 256 x 0.01 mm, as the file's
    # a value typed over the file wins over the file's field of view, which then follows
    typed = parsed(str(path), "--size", "128", "--set", "camera.pixel_pitch=0.01").camera
    assert (typed.width, typed.height, typed.pixel_pitch) == (128, 128, 0.01)


def test_size_against_a_typed_width_is_one_line(tmp_path):
    result = subprocess.run(
        [sys.executable, "-m", "glshade", "measure", "--set", "camera.width=300", "--size", "512"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=120,
    )
    assert result.returncode == 2
    assert result.stderr.splitlines() == [
        "glshade: error: --size 512 and --set camera.width=300 conflict: both set camera.width "
        "(the image's pixels across); give one of them"
    ]


def test_view_applies_size_and_settings_as_render_does():
    # the viewer's --size and --set, through the same function as render's
    typed = ["theta=30", "camera.pixel_pitch=0.01"]
    viewed, _ = parse_sets(typed, Scene(), 256)
    assert viewed == parsed(
        "--set", "theta=30", "--set", "camera.pixel_pitch=0.01", "--size", "256"
    )
    # without --size: the viewer's default, unless the width is typed
    assert parse_sets([], Scene(), None, VIEW_SIZE)[0].camera.width == VIEW_SIZE
    assert parse_sets(["camera.width=300"], Scene(), None, VIEW_SIZE)[0].camera.width == 300
    with pytest.raises(GlshadeError, match="^--size 512 and --set camera.width=300 conflict"):
        parse_sets(["camera.width=300"], Scene(), 512, VIEW_SIZE)


# ------------------------------------------------------------------ one set of short names
def test_short_names_come_from_the_declarations():
    names = short_names()
    assert [p.path for p in names["theta"]] == ["camera.theta_deg"]  # flag and slider agree
    assert [p.path for p in names["stripe_sigma"]] == ["emitter.stripe_sigma"]  # a slider
    assert [p.path for p in names["focus"]] == ["camera.focus_distance"]  # a flag
    assert [p.path for p in names["outside"]] == ["surface.outside"]  # a choice's key
    # every viewer slider is reachable by its name, and names its own parameter
    for name, control in controls().items():
        assert setting_param(name).path == control.param.path
        assert by_name(name) == control
    assert setting_param("f_number").path == "camera.f_number"  # - _ and space alike


@pytest.mark.parametrize("command", ["render", "measure"])
def test_render_and_measure_take_short_names(command):
    args = build_parser(command).parse_args([command, "--set", "theta=5", "--set", "dmax=3um"])
    short = scene_from_args(args)
    args = build_parser(command).parse_args(
        [command, "--set", "camera.theta_deg=5", "--set", "defect.dmax=0.003"]
    )
    assert short == scene_from_args(args)
    assert (short.camera.theta_deg, short.defect.dmax) == (5.0, 0.003)


def test_the_viewers_script_takes_the_same_names():
    scene = paper_scene()
    assert parse_sets(["theta=5"], scene)[0] == parse_sets(["camera.theta_deg=5"], scene)[0]
    assert parse_sets(["theta=5"], scene)[0] == scene.with_value("camera.theta_deg", 5.0)
    # a name without a slider, which the viewer refused before, as render takes it
    assert parse_sets(["focus=300"], scene)[0].camera.focus_distance == 300.0
    # a typed radius is taken as typed (the concave checkbox turns the final one inwards)
    bowl = parse_sets(["surface=sphere", "radius=30", "concave=1"], scene)[0]
    assert bowl.surface.radius == -30.0


def test_render_takes_a_short_name_end_to_end(tmp_path):
    saved = tmp_path / "scene.toml"
    code = main(
        ["render", "--set", "theta=5", "--size", "16", "-o", str(tmp_path / "x.png"),
         "--save-scene", str(saved)]
    )  # fmt: skip
    assert code == 0
    assert Scene.load(saved) == Scene().with_size(16).with_value("camera.theta_deg", 5.0)


@pytest.mark.parametrize(
    ("name", "message"),
    [
        (
            "thta",
            "--set thta: unknown setting; close matches: theta; or a dotted path such as "
            "camera.theta_deg (docs/scene-format.md)",
        ),
        (
            "black_level",
            "--set black_level: ambiguous short name: it may be 'black level' "
            "(emitter.black_level) or 'black-level' (sensor.black_level_dn); type one of those",
        ),
    ],
)
@pytest.mark.parametrize("command", ["render", "measure"])
def test_an_unknown_or_ambiguous_name_is_one_line(tmp_path, capsys, command, name, message):
    assert main([command, "--set", f"{name}=3"]) == 2
    assert capsys.readouterr().err.splitlines() == [f"glshade: error: {message}"]
    with pytest.raises(GlshadeError) as info:
        parse_sets([f"{name}=3"], paper_scene())
    assert str(info.value) == message


def test_the_viewer_offers_its_own_names():
    with pytest.raises(GlshadeError, match="close matches: view"):
        parse_sets(["veiw=overlay"], paper_scene())
