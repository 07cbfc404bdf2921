"""The height-map surface kind: the spline against the NumPy oracle, maps sampling the
paper's sphere and cylinder against the analytic surfaces (the error falls as the
spacing squared, the slope order of the Catmull-Rom spline), outside modes, scene files
and bad input."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from glshade.components.surface.heightmap import catmull_rom, map_bounds
from glshade.measure.single import measure_scene
from glshade.oracle import tracer
from glshade.scene import Scene, paper_scene


def _sample(
    path, surface: Scene, spacing: float, half_x: float = 30.0, half_z: float = 50.0
) -> str:
    """``surface``'s analytic height sampled on a grid (mm), saved as .npy."""
    from glshade.components.registry import registry

    x = np.arange(-half_x, half_x + 1e-9, spacing)
    z = np.arange(-half_z, half_z + 1e-9, spacing)
    xx, zz = np.meshgrid(x, z)
    heights = registry().active(surface).surface.height(surface, xx, zz)
    np.save(path, heights)
    return str(path)


def _map_scene(scene: Scene, file: str, spacing: float, **surface) -> Scene:
    return scene.updated(
        surface={"kind": "heightmap", "file": file, "spacing": (spacing, spacing), **surface}
    )


def test_the_spline_interpolates_and_its_gradient_is_exact():
    rng = np.random.default_rng(3)
    heights = rng.normal(size=(9, 11))
    rows, cols = np.meshgrid(np.arange(9), np.arange(11), indexing="ij")
    f, _, _ = catmull_rom(heights, cols.astype(float), rows.astype(float))
    assert np.allclose(f, heights, atol=1e-14)  # through every sample
    u, v = rng.uniform(0, 10, 200), rng.uniform(0, 8, 200)
    f, fu, fv = catmull_rom(heights, u, v)
    h = 1e-6
    assert fu == pytest.approx(
        (catmull_rom(heights, u + h, v)[0] - catmull_rom(heights, u - h, v)[0]) / (2 * h), abs=1e-6
    )
    assert fv == pytest.approx(
        (catmull_rom(heights, u, v + h)[0] - catmull_rom(heights, u, v - h)[0]) / (2 * h), abs=1e-6
    )
    lo, hi, _ = map_bounds(heights, (1.0, 1.0))
    dense = catmull_rom(heights, *np.meshgrid(np.linspace(0, 10, 301), np.linspace(0, 8, 301)))[0]
    assert lo <= dense.min() and dense.max() <= hi


def test_curvature_bound_holds():
    rng = np.random.default_rng(5)
    heights = rng.normal(size=(12, 12)) * 0.01
    spacing = (0.5, 0.25)
    _, _, bound = map_bounds(heights, spacing)
    u, v = np.meshgrid(np.linspace(0, 11, 200), np.linspace(0, 11, 200))
    h = 1e-4

    def f(du, dv):
        return catmull_rom(heights, u + du, v + dv)[0]

    fxx = (f(h, 0) - 2 * f(0, 0) + f(-h, 0)) / (h * spacing[0]) ** 2
    fzz = (f(0, h) - 2 * f(0, 0) + f(0, -h)) / (h * spacing[1]) ** 2
    fxz = (f(h, h) - f(h, -h) - f(-h, h) + f(-h, -h)) / (4 * h * h * spacing[0] * spacing[1])
    inner = (u > 0.01) & (u < 10.99) & (v > 0.01) & (v < 10.99)
    largest = np.abs(0.5 * (fxx + fzz)) + np.hypot(0.5 * (fxx - fzz), fxz)
    assert largest[inner].max() <= bound


@pytest.mark.parametrize("kind", ["sphere", "cylinder"])
def test_sampled_paper_surfaces_converge_to_the_analytic_ones(renderer, tmp_path, kind):
    """fp64 uv error against the analytic surface falls ~4x per halving of the spacing."""
    analytic = paper_scene(kind, theta_deg=45.0).with_size(96).updated(render={"precision": "fp64"})
    truth = renderer.render(analytic, ("uv", "mask"))
    errors = []
    for spacing in (1.0, 0.5, 0.25):
        file = _sample(tmp_path / f"{kind}_{spacing}.npy", analytic, spacing, 25.0, 40.0)
        frame = renderer.render(_map_scene(analytic, file, spacing), ("uv", "mask"))
        both = truth.mask & frame.mask
        assert both.sum() > 0.9 * truth.mask.sum()
        errors.append(float(np.abs(frame.uv - truth.uv)[both].max()))
    assert errors[2] < 2e-3
    assert errors[0] / errors[1] > 3.0 and errors[1] / errors[2] > 3.0, errors


@pytest.mark.parametrize("kind", ["sphere", "cylinder"])
def test_a_sampled_paper_surface_is_as_visible(renderer, tmp_path, kind):
    sphere = paper_scene(kind, theta_deg=45.0, sigma2=1.0, dmax=0.005).with_size(512)
    file = _sample(tmp_path / f"{kind}.npy", sphere, 0.25, 25.0, 40.0)
    a, b = measure_scene(renderer, sphere), measure_scene(renderer, _map_scene(sphere, file, 0.25))
    assert a.visibility_px == b.visibility_px > 0
    assert b.deflection_px == pytest.approx(a.deflection_px, abs=0.01)


@pytest.mark.parametrize("outside", ["curtain", "flat"])
@pytest.mark.parametrize("precision, tol", [("fp32", 5e-4), ("fp64", 1e-6)])
def test_a_wavy_map_agrees_with_the_oracle(renderer, tmp_path, outside, precision, tol):
    x = np.arange(-12.0, 12.0 + 1e-9, 0.4)
    xx, zz = np.meshgrid(x, x)
    heights = 0.004 * np.sin(xx / 1.7) * np.cos(zz / 2.3) - 0.0002 * xx * zz
    np.save(tmp_path / "wavy.npy", heights)
    scene = _map_scene(
        paper_scene(theta_deg=40.0).with_size(40), str(tmp_path / "wavy.npy"), 0.4, outside=outside
    )
    scene = scene.updated(render={"precision": precision})
    shader = renderer.render(scene, ("uv", "mask"))
    oracle = tracer.trace(scene, ("uv", "mask"))
    assert (shader.mask != oracle.mask).sum() <= 2
    both = shader.mask & oracle.mask
    assert both.sum() > 200
    assert np.abs(shader.uv - oracle.uv)[both].max() < tol
    if outside == "curtain":
        assert not shader.mask.all()  # the map is smaller than the view: the rays beyond it miss
    else:
        assert shader.mask.sum() > scene.camera.width * scene.camera.height * 0.9


def test_relative_paths_follow_the_scene_file(tmp_path, renderer):
    (tmp_path / "maps").mkdir()
    np.save(tmp_path / "maps" / "m.npy", np.zeros((8, 8)))
    scene_file = tmp_path / "maps" / "part.toml"
    scene_file.write_text(
        '[surface]\nkind = "heightmap"\nfile = "m.npy"\nspacing = [2.0, 2.0]\noutside = "flat"\n'
    )
    scene = Scene.load(scene_file)
    assert scene.surface.file == str(tmp_path / "maps" / "m.npy")
    scene.save(tmp_path / "maps" / "again.toml")
    assert 'file = "m.npy"' in (tmp_path / "maps" / "again.toml").read_text()
    flat = renderer.render(paper_scene().with_size(24), ("uv",)).uv
    assert np.nanmax(np.abs(renderer.render(scene.with_size(24), ("uv",)).uv - flat)) < 1e-3


@pytest.mark.parametrize(
    "setup, args, fragment",
    [
        (
            None,
            ["--set", "surface.file=missing.npy", "--set", "surface.spacing=1,1"],
            "surface.file",
        ),
        ("nan", ["--set", "surface.file=bad.npy", "--set", "surface.spacing=1,1"], "NaN"),
        ("small", ["--set", "surface.file=small.npy", "--set", "surface.spacing=1,1"], "4"),
        ("good", ["--set", "surface.file=good.npy"], "surface.spacing: must be set"),
        (
            "good",
            ["--set", "surface.file=good.npy", "--set", "surface.spacing=0,1"],
            "surface.spacing",
        ),
        (None, [], "surface.file: must be set"),
    ],
)
def test_bad_height_maps_are_one_line(tmp_path, setup, args, fragment):
    if setup == "nan":
        heights = np.zeros((8, 8))
        heights[2, 3] = np.nan
        np.save(tmp_path / "bad.npy", heights)
    elif setup == "small":
        np.save(tmp_path / "small.npy", np.zeros((3, 8)))
    elif setup == "good":
        np.save(tmp_path / "good.npy", np.zeros((8, 8)))
    before = sorted(p.name for p in tmp_path.iterdir())
    result = subprocess.run(
        [sys.executable, "-m", "glshade", "render", "--surface", "heightmap", "--size", "8", *args],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=120,
    )
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2 and len(lines) == 1 and fragment in lines[0], result.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == before
