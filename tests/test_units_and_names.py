"""Units and names everywhere: a quantity with its unit wherever a number is typed (scene
files, ``Scene.with_value``, ``--family``, ``--over``, sweep grids), errors that name what
the user typed, formula parameters by ``--set``, and ``--save-scene`` on every command that
takes a scene (the file written reads back to the same scene and the same numbers)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from glshade.app.args import parse_setting
from glshade.errors import GlshadeError, SceneError
from glshade.scene import Scene
from glshade.sweep.optimize import parse_family, parse_over


def cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "glshade", *args], capture_output=True, text=True, timeout=300
    )


def test_a_scene_file_takes_quantities_with_units(tmp_path):
    path = tmp_path / "units.toml"
    path.write_text(
        '[camera]\ntheta_deg = "0.2 rad"\ndistance = "17.56 cm"\n'
        '[emitter]\nhalf_size = ["15 cm", 100]\n'
        '[defect]\ndmax = "5 um"\nsigma2 = "4e6 um2"\n'
    )
    scene = Scene.load(path)
    assert scene.camera.theta_deg == pytest.approx(11.459155902616466)
    assert scene.camera.distance == pytest.approx(175.6)
    assert scene.emitter.half_size == pytest.approx((150.0, 100.0))
    assert scene.defect.dmax == pytest.approx(0.005)
    assert scene.defect.sigma_x2 == pytest.approx(4.0)
    # written back as plain numbers in the documented units: the same scene
    scene.save(tmp_path / "again.toml")
    assert Scene.load(tmp_path / "again.toml") == scene


def test_with_value_takes_a_unit_and_a_bad_one_is_named():
    assert Scene().with_value("defect.dmax", "3um").defect.dmax == pytest.approx(0.003)
    assert Scene().with_value("camera.theta_deg", "0.5 rad").camera.theta_deg == pytest.approx(
        28.64788975654116
    )
    with pytest.raises(SceneError, match=r"defect.dmax: .*got '5 furlongs'"):
        Scene().with_value("defect.dmax", "5 furlongs")


def test_family_and_over_take_units():
    family = parse_family("defect.dmax=3um..5um,defect.sigma2=1|4e6um2")
    assert sorted({round(m["defect.dmax"], 9) for m in family}) == [0.003, 0.004, 0.005]
    assert sorted({m["defect.sigma2"] for m in family}) == [1.0, 4.0]
    (over,) = parse_over("camera.theta_deg=5deg..0.5rad")
    assert (over.lo, over.hi) == pytest.approx((5.0, 28.64788975654116))
    with pytest.raises(GlshadeError, match="--family defect.dmax: expected a number in mm"):
        parse_family("defect.dmax=3kg..5um")


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (["--sigma2", "0"], "--sigma2 (defect.sigma2): must be a finite number > 0"),
        (["--set", "defect.sigma2=0"], "defect.sigma2: must be a finite number > 0"),
        (["--theta", "95"], "--theta (camera.theta_deg): must be in (0, 90) degrees"),
    ],
)
def test_errors_name_what_was_typed(args, named):
    result = cli("render", "-o", "never.png", "--size", "16", *args)
    assert result.returncode == 2 and named in result.stderr
    assert "sigma_x2" not in result.stderr and len(result.stderr.strip().splitlines()) == 1


def test_a_scene_files_shorthand_is_named_as_written(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text("[defect]\nsigma2 = -4\n")
    with pytest.raises(SceneError) as info:
        Scene.load(path)
    assert info.value.field == "defect.sigma2"


def test_formula_parameters_by_set():
    scene = Scene().with_values(
        [
            ("surface.kind", "formula"),
            ("surface.expression", "a*x*x + b*z*z"),
            ("surface.parameters", {"a": 0.0, "b": 5e-4}),
        ]
    )
    tables: dict = {}
    path, value = parse_setting("surface.parameters.a=1e-3", scene, tables)
    tables.setdefault("surface", {})["parameters"] = value
    assert path == "surface.parameters"
    assert dict(value) == {"a": 1e-3, "b": 5e-4}  # the scene's other entry kept
    _, value = parse_setting("surface.parameters.b=2e-3", scene, tables)
    assert dict(value) == {"a": 1e-3, "b": 2e-3}  # and the one set before
    assert scene.updated(surface={"parameters": value}).value("surface.parameters") == value
    with pytest.raises(GlshadeError, match="camera.theta_deg is not a table"):
        parse_setting("camera.theta_deg.x=1", scene, {})


@pytest.mark.parametrize("command", ["render", "measure", "optimize"])
def test_save_scene_on_every_command_that_takes_a_scene(tmp_path, command):
    saved = tmp_path / "scene.toml"
    extra = {
        "render": ["-o", str(tmp_path / "img.png")],
        "measure": ["--json"],
        "optimize": ["--over", "camera.theta_deg=30..60", "--grid", "2", "--refine", "0"],
    }[command]
    typed = [
        "--surface",
        "cylinder",
        "--theta",
        "40",
        "--dmax",
        "4um",
        "--size",
        "96",
        "--period",
        "auto",
    ]
    result = cli(command, *typed, "--save-scene", str(saved), *extra)
    assert result.returncode == 0, result.stderr
    scene = Scene.load(saved)
    assert scene.surface.kind == "cylinder" and scene.defect.dmax == pytest.approx(0.004)
    assert scene.camera.width == 96
    if command == "measure":  # the file measures exactly as the flags did
        again = cli("measure", str(saved), "--json")
        first, second = json.loads(result.stdout), json.loads(again.stdout)
        first.pop("seconds"), second.pop("seconds")
        assert first == second


def test_save_scene_is_refused_before_any_work(tmp_path):
    result = cli("measure", "--size", "16", "--save-scene", str(tmp_path / "scene.png"))
    assert result.returncode == 2 and "--save-scene" in result.stderr
    assert not any(tmp_path.iterdir())
