"""The formula surface kind (paper eq. 3): the GLSL against the NumPy oracle, the sphere
written as a formula against the analytic sphere, scene files and the CLI."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from glshade.errors import SceneError
from glshade.instruments.stripes.single import measure_scene
from glshade.oracle import tracer
from glshade.scene import Scene, paper_scene

SPHERE_SAG = "-(x^2 + z^2) / (R + sqrt(R^2 - x^2 - z^2))"


def _formula(scene: Scene, expression: str, parameters=()) -> Scene:
    return scene.updated(
        surface={"kind": "formula", "expression": expression, "parameters": parameters}
    )


def _sphere(theta: float, size: int) -> Scene:
    """A 500 mm sphere: the region the camera sees stays inside it (the formula's bounds
    are taken over that region; a 70 mm sphere's edge is in view at low θ)."""
    flat = paper_scene("flat", theta_deg=theta, sigma2=1.0, dmax=0.005).with_size(size)
    return flat.updated(surface={"kind": "sphere", "radius": 500.0})


@pytest.mark.parametrize("precision, tol_mm", [("fp32", 1e-3), ("fp64", 1e-9)])
@pytest.mark.parametrize("theta", [45.0, 15.0])
def test_the_sphere_as_a_formula_renders_as_the_sphere(renderer, precision, tol_mm, theta):
    sphere = _sphere(theta, 96).updated(render={"precision": precision})
    written = _formula(sphere, SPHERE_SAG, {"R": sphere.surface.radius})
    a = renderer.render(sphere, ("uv", "mask"))
    b = renderer.render(written, ("uv", "mask"))
    assert np.array_equal(a.mask, b.mask) and a.mask.mean() > 0.7
    assert np.nanmax(np.abs(a.uv - b.uv)) < tol_mm


def test_the_sphere_as_a_formula_is_as_visible(renderer):
    sphere = _sphere(45.0, 512)
    written = _formula(sphere, SPHERE_SAG, {"R": sphere.surface.radius})
    a, b = measure_scene(renderer, sphere), measure_scene(renderer, written)
    assert a.visibility_px == b.visibility_px == 6.0
    assert b.deflection_px == pytest.approx(a.deflection_px, abs=1e-3)


@pytest.mark.parametrize("theta", [45.0, 10.0])
def test_a_wavy_saddle_agrees_with_the_oracle(renderer, theta):
    scene = _formula(
        paper_scene(theta_deg=theta).with_size(48),
        "0.0005*x^2 - 0.0002*z^2 + a*sin(z/b)",
        {"a": 0.002, "b": 5.0},
    )
    shader = renderer.render(scene, ("uv", "mask"))
    oracle = tracer.trace(scene, ("uv", "mask"))
    assert np.array_equal(shader.mask, oracle.mask)
    assert np.nanmax(np.abs(shader.uv - oracle.uv)) < 5e-4


#: Each function of the grammar as a surface of the paper's scene (x -30..30, z -40..36 mm
#: in view at 45°); abs, min and max put kinks in view.
FUNCTION_SURFACES = {
    "sqrt": "0.01*sqrt(x^2 + z^2 + 100)",
    "exp": "0.001*exp(x/20)",
    "log": "0.001*log(x^2 + z^2 + 10)",
    "sin": "0.002*sin(z/5)",
    "cos": "0.002*cos(x/4)",
    "tan": "0.001*tan(z/60)",
    "abs": "0.001*abs(x - 3) - 0.002*abs(z + 5)",
    "min": "0.001*min(x, z)",
    "max": "0.001*max(x, z, 2)",
}


@pytest.mark.parametrize("name", sorted(FUNCTION_SURFACES))
def test_each_function_renders_as_the_oracle_traces_it(renderer, name):
    scene = _formula(paper_scene(theta_deg=45.0).with_size(32), FUNCTION_SURFACES[name])
    shader = renderer.render(scene, ("uv", "mask"))
    oracle = tracer.trace(scene, ("uv", "mask"))
    assert np.array_equal(shader.mask, oracle.mask) and shader.mask.all()
    assert np.nanmax(np.abs(shader.uv - oracle.uv)) < 5e-4


@pytest.mark.parametrize(
    "expression, precision, fragment",
    [
        ("exp(x)", "fp32", "f = 1.42e+09 mm at x = 21.07, z = -40.4 mm is not allowed; "),
        ("1/x", "fp32", "f = inf mm at x = 0, z = -40.4 mm is not allowed; "),
        (
            "x^64*1e-150",
            "fp32",
            "x**64 = 3.23e+94 at x = -29.97, z = -40.4 mm, which overflows in single precision",
        ),
        ("1e-3*sin(1e7*x)", "fp64", "a curvature bound of"),
        ("log(x - 1000)", "fp32", "a formula with finite values where the camera looks"),
    ],
)
def test_values_beyond_range_where_the_camera_looks_are_refused(expression, precision, fragment):
    from glshade.components.surface.formula import bounds

    scene = _formula(paper_scene().with_size(16), expression)
    scene = scene.updated(render={"precision": precision})
    with pytest.raises(SceneError) as info:
        bounds(scene)
    message = str(info.value)
    assert fragment in message and "\n" not in message, message
    assert message.startswith("surface.expression: ")


def test_single_precision_overflow_is_checked_only_for_fp32():
    from glshade.components.surface.formula import bounds

    scene = _formula(paper_scene(), "x^64*1e-150").updated(render={"precision": "fp64"})
    lo, hi, _ = bounds(scene)
    assert -1e-8 < lo < hi < 1e-8


def test_scene_file_of_spec_8_1(tmp_path):
    path = tmp_path / "panel.toml"
    path.write_text(
        '[surface]\nkind = "formula"\nexpression = "0.0005*x^2 - 0.0002*z^2 + a*sin(z/b)"\n'
        "parameters = { a = 0.002, b = 5.0 }\n"
    )
    scene = Scene.load(path)
    assert scene.surface.parameters == (("a", 0.002), ("b", 5.0))
    scene.save(tmp_path / "again.toml")
    assert Scene.load(tmp_path / "again.toml") == scene
    assert scene.title().startswith("y = 0.0005*x^2 - 0.0002*z^2 + a*sin(z/b)")


def test_fp64_refuses_what_glsl_has_no_double_for():
    scene = _formula(paper_scene(), "sin(x)").updated(render={"precision": "fp64"})
    from glshade.gpu.compose import ShaderFeatures

    with pytest.raises(
        SceneError, match="render.precision: must be fp32 for this formula: GLSL has no double"
    ):
        ShaderFeatures.from_scene(scene)


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["--set", "surface.expression=x;y"], "surface.expression: ';' at column 2 is not allowed"),
        (["--set", "surface.expression=a*x"], "the undeclared name 'a' at column 1"),
        (["--set", "surface.expression=__import__('os')"], "surface.expression:"),
        (["--set", "surface.parameters=x=1"], "surface.parameters: must be parameter names"),
        (
            ["--set", "surface.expression=sin(x)", "--precision", "fp64"],
            "GLSL has no double-precision version of sin",
        ),
        (["--set", "surface.expression=1e999*x"], "the number 1e999 at column 1 is not allowed"),
        (
            ["--set", "surface.expression=1" + "0" * 400 + "*x"],
            "the number 100000000000...000000 (401 characters) at column 1 is not allowed; "
            "numbers, parameters and the constants they fold to must lie within ±3.4e+38",
        ),
        (["--set", "surface.expression=x^100000"], "the power 100000 at column 3"),
        (["--set", "surface.expression=exp(x)"], "f = 1.25e+09 mm at x = 20.94, z = -37.66 mm"),
        (
            ["--set", "surface.expression=a*x", "--set", "surface.parameters.a=1e400"],
            "surface.parameters.a: must be a finite number, got inf",
        ),
        (
            ["--set", "surface.expression=a*x", "--set", "surface.parameters.a=-1e39"],
            "surface.parameters.a: must be a finite number within ±3.4e+38 (a number beyond "
            "±1.8e308, such as 1e400, reads as inf), got -1e+39",
        ),
    ],
)
def test_bad_formulas_on_the_command_line(tmp_path, args, fragment):
    result = subprocess.run(
        [sys.executable, "-m", "glshade", "render", "--surface", "formula", "--size", "8", *args],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=120,
    )
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2 and len(lines) == 1 and fragment in lines[0], result.stderr
    assert list(tmp_path.iterdir()) == []


def test_a_study_runs_on_free_form_scene_files(tmp_path):
    from pathlib import Path

    from glshade.app.cli import main
    from glshade.study.store import read_results_csv

    root = Path(__file__).resolve().parents[1] / "examples"
    saddle, panel = str(root / "saddle.toml"), str(root / "panel.toml")
    out = tmp_path / "study"
    assert (
        main(
            [
                "paper",
                "--surfaces",
                f"flat,{saddle},{panel}",
                "--thetas",
                "45,15",
                "--sigma2s",
                "4",
                "--dmaxs",
                "5um",
                "--size",
                "96",
                "--out",
                str(out),
                "--no-progress",
            ]
        )
        == 0
    )
    rows = read_results_csv(out / "results.csv")
    assert [r.surface for r in rows].count(saddle) == 2 and [r.surface for r in rows].count(
        panel
    ) == 2
    assert {"grid_saddle_dmax5um.png", "visibility_panel_dmax5um.png"} <= {
        p.name for p in out.iterdir()
    }
    assert "saddle.toml" in (out / "report.md").read_text()
    assert (
        main(
            [
                "paper",
                "--surfaces",
                f"{saddle},{tmp_path / 'x' / 'saddle.toml'}",
                "--out",
                str(tmp_path / "b"),
            ]
        )
        == 2
    )


@pytest.mark.parametrize(
    "value, refusal",
    [
        ("1e400", "must be a finite number, got inf"),  # tomllib reads 1e400 as inf
        ("-1e400", "must be a finite number, got -inf"),
        ("nan", "must be a finite number, got nan"),
        ("1e39", "must be a finite number within ±3.4e+38"),
    ],
)
def test_parameters_out_of_range_in_a_scene_file(tmp_path, value, refusal):
    path = tmp_path / "panel.toml"
    path.write_text(
        f'[surface]\nkind = "formula"\nexpression = "a*x"\nparameters = {{ a = {value} }}\n'
    )
    result = subprocess.run(
        [sys.executable, "-m", "glshade", "render", str(path), "--size", "8", "-o", "out.png"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=120,
    )
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2 and len(lines) == 1, result.stderr
    assert lines[0].startswith(f"glshade: error: surface.parameters.a: {refusal}")
    assert not (tmp_path / "out.png").exists()


def test_abs_min_max_render_from_the_command_line(tmp_path):
    expression = "0.001*abs(x - 3) + 0.001*min(x, z) - 0.001*max(x, z, 2)"
    result = subprocess.run(
        [sys.executable, "-m", "glshade", "render", "--surface", "formula", "--size", "16"]
        + ["--set", f"surface.expression={expression}", "-o", "out.png"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=120,
    )
    assert result.returncode == 0 and result.stderr == "", result.stderr
    assert (tmp_path / "out.png").stat().st_size > 0
