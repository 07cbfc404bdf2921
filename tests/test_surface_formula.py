"""The formula surface kind (paper eq. 3): the GLSL against the NumPy oracle, the sphere
written as a formula against the analytic sphere, scene files and the CLI."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from glshade.errors import SceneError
from glshade.measure.single import measure_scene
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
