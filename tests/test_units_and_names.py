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
        (["--sigma2", "0"], "--sigma2 (defect.sigma2): must be in (1e-06, 1e+08) mm²"),
        (["--set", "defect.sigma2=0"], "defect.sigma2: must be in (1e-06, 1e+08) mm²"),
        (["--theta", "95"], "--theta (camera.theta_deg): must be in (0.001, 90) degrees"),
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


def _viewer_missing() -> str | None:
    import os
    import shutil

    try:
        import imgui_bundle  # noqa: F401
        import moderngl_window  # noqa: F401
    except ImportError as exc:
        return f"the viewer extra is not installed ({exc.name})"
    if not os.environ.get("DISPLAY") and shutil.which("xvfb-run") is None:
        return "no display and no xvfb-run to make one"
    return None


def cli_view(*args: str) -> subprocess.CompletedProcess:
    import os

    command = [sys.executable, "-m", "glshade", "view", *args]
    if not os.environ.get("DISPLAY"):
        command = ["xvfb-run", "-a", "-s", "-screen 0 1280x1024x24", *command]
    return subprocess.run(command, capture_output=True, text=True, timeout=300)


TYPED = [
    "--surface", "cylinder", "--theta", "40", "--dmax", "4um", "--size", "96",
    "--period", "auto", "--wavelength", "550nm", "--set", "defect.x0=0.5mm",
]  # fmt: skip


@pytest.mark.parametrize(
    "command",
    [
        "render",
        "measure",
        "optimize",
        pytest.param(
            "view",
            marks=pytest.mark.skipif(_viewer_missing() is not None, reason=str(_viewer_missing())),
        ),
    ],
)
def test_save_scene_on_every_command_that_takes_a_scene(tmp_path, command):
    from glshade.app.args import scene_from_args
    from glshade.app.cli import build_parser

    saved = tmp_path / "scene.toml"
    extra = {
        "render": ["-o", str(tmp_path / "img.png")],
        "measure": ["--json"],
        "optimize": ["--over", "camera.theta_deg=30..60", "--grid", "2", "--refine", "0"],
    }.get(command, [])
    if command == "view":  # the viewer's own --set names; any dotted path as render's
        typed = ["--size", "96", "--set", "camera.theta_deg=40", "--set", "defect.dmax=4um"]
        typed += ["--set", "surface.kind=cylinder", "--frames", "1"]
        result = cli_view(*typed, "--save-scene", str(saved))
        expected = (
            Scene()
            .with_size(96)
            .with_values(
                [("camera.theta_deg", 40.0), ("defect.dmax", 0.004), ("surface.kind", "cylinder")]
            )
        )
    else:
        result = cli(command, *TYPED, "--save-scene", str(saved), *extra)
        expected = scene_from_args(build_parser().parse_args([command, *TYPED, *extra]))
    assert result.returncode == 0, result.stderr
    scene = Scene.load(saved)
    assert scene == expected  # every value as the command used it
    assert scene.surface.kind == "cylinder" and scene.defect.dmax == pytest.approx(0.004)
    assert scene.camera.width == 96
    if command == "measure":  # the file measures exactly as the flags did
        again = cli("measure", str(saved), "--json")
        first, second = json.loads(result.stdout), json.loads(again.stdout)
        first.pop("seconds"), second.pop("seconds")
        assert first == second


def test_measure_from_its_saved_scene_gives_the_same_numbers(tmp_path):
    """A scene with every kind of value the file must carry back: a formula and its
    parameters set one by one, quantities with units, a non-square image, the period
    chosen automatically, a noisy sensor."""
    saved = tmp_path / "scene.toml"
    typed = [
        "--surface", "formula",
        "--set", "surface.expression=a*x*x + b*z*z",
        "--set", "surface.parameters.a=2e-4",
        "--set", "surface.parameters.b=-1e-4",
        "--theta", "0.6rad", "--dmax", "4um", "--sigma2", "2e6um2",
        "--set", "camera.width=64", "--set", "camera.height=48",
        "--period", "auto", "--height-rms", "10nm", "--full-well", "20000",
    ]  # fmt: skip
    first = cli("measure", *typed, "--save-scene", str(saved), "--json")
    assert first.returncode == 0, first.stderr
    again = cli("measure", str(saved), "--json")
    assert again.returncode == 0, again.stderr
    one, two = json.loads(first.stdout), json.loads(again.stdout)
    one.pop("seconds"), two.pop("seconds")
    assert one == two and one["size"] == [64, 48]
    scene = Scene.load(saved)
    assert scene.surface.parameters == (("a", 2e-4), ("b", -1e-4))
    assert scene.camera.theta_deg == pytest.approx(34.37746770784939)
    assert scene.render.height_rms_um == pytest.approx(0.01)
    scene.save(tmp_path / "again.toml")  # and saving the loaded scene changes nothing
    assert (tmp_path / "again.toml").read_text() == saved.read_text()


def test_save_scene_is_refused_before_any_work(tmp_path):
    result = cli("measure", "--size", "16", "--save-scene", str(tmp_path / "scene.png"))
    assert result.returncode == 2 and "--save-scene" in result.stderr
    assert not any(tmp_path.iterdir())


def test_lengths_kept_in_micrometres_take_a_unit(tmp_path):
    assert Scene().with_value("render.wavelength_um", "550 nm").render.wavelength_um == (
        pytest.approx(0.55)
    )
    path = tmp_path / "rough.toml"
    path.write_text('[render]\nheight_rms_um = "20 nm"\nwavelength_um = "0.6 um"\n')
    scene = Scene.load(path)
    assert scene.render.height_rms_um == pytest.approx(0.02)
    assert scene.render.wavelength_um == pytest.approx(0.6)
    parsed = parse_setting("render.wavelength_um=0.0005mm")[1]
    assert parsed == pytest.approx(0.5)
    with pytest.raises(SceneError, match=r"render.wavelength_um: .*µm.*got '5 furlongs'"):
        Scene().with_value("render.wavelength_um", "5 furlongs")


def test_a_bad_unit_in_a_scene_file_is_one_line_naming_the_key(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('[defect]\ndmax = "5 furlongs"\n')
    result = cli("render", str(path), "-o", str(tmp_path / "never.png"))
    assert result.returncode == 2 and "Traceback" not in result.stderr
    (line,) = result.stderr.strip().splitlines()
    assert line.startswith("glshade: error: defect.dmax: ") and "got '5 furlongs'" in line
    assert "a number in mm, or with a unit" in line
    assert not any(p.name == "never.png" for p in tmp_path.iterdir())


def formula_scene() -> Scene:
    return Scene().with_values(
        [
            ("surface.kind", "formula"),
            ("surface.expression", "a*x*x + b*z*z"),
            ("surface.parameters", {"a": 0.0, "b": 5e-4}),
        ]
    )


def test_a_formula_parameter_by_its_dotted_path_everywhere(tmp_path):
    from glshade.app.viewer.controls import parse_sets
    from glshade.sweep.spec import spec_from_dict

    scene = formula_scene()
    # Scene.with_value and Scene.value: the entry set, the others kept
    changed = scene.with_value("surface.parameters.a", 1e-3)
    assert changed.surface.parameters == (("a", 1e-3), ("b", 5e-4))
    assert changed.value("surface.parameters.a") == 1e-3
    assert scene.with_value("surface.parameters.b", "2e-3").value("surface.parameters.b") == 2e-3
    # set together with the kind and the expression, as a file would
    alone = Scene().with_values(
        [
            ("surface.kind", "formula"),
            ("surface.expression", "c*x*x"),
            ("surface.parameters.c", 1e-3),
        ]
    )
    assert alone.surface.parameters == (("c", 1e-3),)
    # the viewer's --set, as render's
    viewed, _ = parse_sets(["surface.parameters.a=3e-3"], scene)
    assert viewed.surface.parameters == (("a", 3e-3), ("b", 5e-4))
    # a sweep axis, and its column in the table
    base = tmp_path / "formula.toml"
    scene.save(base)
    spec = spec_from_dict(
        {"base": base.name, "size": 16, "grid": {"surface.parameters.a": [0, "1e-3"]}},
        tmp_path,
    )
    cases = spec.cases()
    assert [c.scene.value("surface.parameters.a") for c in cases] == [0.0, 1e-3]
    assert [c.scene.value("surface.parameters.b") for c in cases] == [5e-4, 5e-4]
    assert spec.swept_values(cases[1]) == {"surface.parameters.a": 1e-3}
    # the optimiser's keys
    (over,) = parse_over("surface.parameters.a=0..0.002")
    assert (over.key, over.lo, over.hi) == ("surface.parameters.a", 0.0, 0.002)
    assert parse_family("surface.parameters.b=1e-4|2e-4") == [
        {"surface.parameters.b": 1e-4},
        {"surface.parameters.b": 2e-4},
    ]


def test_a_formula_parameter_is_checked_as_the_file_checks_it(tmp_path):
    scene = formula_scene()
    with pytest.raises(SceneError, match=r"^surface.parameters.a: must be a finite number"):
        scene.with_value("surface.parameters.a", float("nan"))
    with pytest.raises(SceneError, match=r"surface.parameters.a: .*without a unit.*got '2um'"):
        scene.with_value("surface.parameters.a", "2um")
    with pytest.raises(GlshadeError, match=r"surface.parameters.a: .*without a unit"):
        parse_setting("surface.parameters.a=2um", scene, {})
    with pytest.raises(SceneError, match="camera.theta_deg is not a table"):
        scene.with_value("camera.theta_deg.x", 1.0)
    with pytest.raises(SceneError, match="surface.parameters.NAME"):
        scene.with_value("surface.parameters.2x", 1.0)
    with pytest.raises(SceneError, match="undeclared name 'a'"):  # the formula's own check
        Scene().with_values(
            [
                ("surface.kind", "formula"),
                ("surface.expression", "a*x*x"),
                ("surface.parameters.b", 1.0),
            ]
        )
    # on the command line: one line, exit 2
    result = cli(
        "render", "--surface", "formula", "--set", "surface.expression=a*x*x",
        "--set", "surface.parameters.a=nan", "-o", str(tmp_path / "never.png"),
    )  # fmt: skip
    assert result.returncode == 2 and len(result.stderr.strip().splitlines()) == 1
    assert "surface.parameters.a: must be a finite number, got nan" in result.stderr


def test_sweep_ranges_take_units(tmp_path):
    from glshade.sweep.spec import spec_from_dict

    spec = spec_from_dict(
        {
            "grid": {
                "defect.sigma2": {"start": "1 mm2", "stop": "4e6 um2", "num": 2},
                "camera.theta_deg": {"start": "5 deg", "stop": 25, "step": "0.17453292519943 rad"},
                "render.wavelength_um": ["550 nm"],
            }
        }
    )
    sigma2, theta, wavelength = (axis.labels for axis in spec.axes)
    assert sigma2 == pytest.approx((1.0, 4.0))
    assert theta == pytest.approx((5.0, 15.0, 25.0))
    assert wavelength == pytest.approx((0.55,))
    with pytest.raises(GlshadeError) as info:
        spec_from_dict({"grid": {"defect.dmax": {"start": "3 furlongs", "stop": 1, "num": 2}}})
    assert "grid.defect.dmax.start" in str(info.value) and "'3 furlongs'" in str(info.value)
    # a bad value is named once, by the grid's key
    with pytest.raises(GlshadeError) as info:
        spec_from_dict({"grid": {"defect.dmax": ["3 furlongs"]}}, source="s.toml")
    assert str(info.value).startswith("s.toml: grid.defect.dmax: must be")
    # a whole table and one of its entries are not two axes
    with pytest.raises(GlshadeError, match="set by two axes"):
        spec_from_dict(
            {
                "grid": {
                    "f": [{"label": "x", "surface.parameters": {"a": 1.0}}],
                    "surface.parameters.a": [1.0, 2.0],
                }
            }
        )


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (["--bit-depth", "13"], "--bit-depth (sensor.bit_depth): must be one of 8, 10, 12, 16"),
        (["--distortion=-20,0,0,0,0"], "--distortion (camera.distortion): must be coefficients"),
        (["--size", "0"], "--size (camera.width): must be an integer in [1, 16384]"),
        (["--set", "sensor.bit_depth=13"], "error: sensor.bit_depth: must be one of"),
    ],
)
def test_checks_over_several_values_name_the_flag(args, named, capsys):
    from glshade.app.cli import main

    assert main(["render", "-o", "never.png", *args]) == 2
    err = capsys.readouterr().err
    assert named in err and len(err.strip().splitlines()) == 1


def test_the_viewers_settings_are_named_as_typed():
    from glshade.app.viewer.controls import parse_sets

    with pytest.raises(SceneError) as info:
        parse_sets(["sigma2=0"], Scene())
    assert str(info.value).startswith("--set sigma2 (defect.sigma2): must be in (1e-06, 1e+08) mm²")
    with pytest.raises(SceneError, match=r"^--set theta \(camera.theta_deg\): must be a number"):
        parse_sets(["theta=abc"], Scene())
    with pytest.raises(SceneError, match=r"^camera.theta_deg: must be in \(0.001, 90\)"):
        parse_sets(["camera.theta_deg=95"], Scene())  # a dotted path is named as it is
    result = cli("view", "--size", "0", "--frames", "1")
    assert result.returncode == 2
    assert "--size (camera.width): must be an integer in [1, 16384], got 0" in result.stderr
