"""The height-map surface kind: the spline against the NumPy oracle, maps sampling the
paper's sphere and cylinder against the analytic surfaces (the error falls as the
spacing squared, the slope order of the Catmull-Rom spline), outside modes, scene files
and bad input."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from glshade.components.surface.heightmap import (
    MapCoverage,
    catmull_rom,
    fill_harmonic,
    fill_nearest,
    grid_of,
    map_bounds,
    split_texture,
)
from glshade.errors import SceneError
from glshade.instruments.stripes.single import measure_scene
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
        ("inf", ["--set", "surface.file=bad.npy", "--set", "surface.spacing=1,1"], "Inf"),
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
    if setup == "inf":
        heights = np.zeros((8, 8))
        heights[2, 3] = np.inf
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


# ------------------------------------------------------------------ unmeasured samples
def _holed_map(path, spacing=0.4, half=12.0):
    """The wavy map with a NaN patch right of the dent (on the camera's side of it), a
    NaN corner and a lone NaN sample; saved as .npy."""
    x = np.arange(-half, half + 1e-9, spacing)
    xx, zz = np.meshgrid(x, x)
    heights = 0.004 * np.sin(xx / 1.7) * np.cos(zz / 2.3) - 0.0002 * xx * zz
    heights[20:30, 35:45] = np.nan
    heights[:3, :4] = np.nan
    heights[45, 12] = np.nan
    np.save(path, heights)
    return str(path), heights


@pytest.mark.parametrize("precision, tol", [("fp32", 5e-4), ("fp64", 1e-6)])
def test_holes_are_misses_on_the_gpu_and_in_the_oracle(renderer, tmp_path, precision, tol):
    file, heights = _holed_map(tmp_path / "holed.npy")
    base = paper_scene(theta_deg=40.0).with_size(40).updated(render={"precision": precision})
    holed = _map_scene(base, file, 0.4)
    filled = _map_scene(base, file, 0.4, fill="harmonic")
    shader = renderer.render(holed, ("uv", "mask"))
    oracle = tracer.trace(holed, ("uv", "mask"))
    assert (shader.mask != oracle.mask).sum() <= 2
    both = shader.mask & oracle.mask
    assert both.sum() > 200
    assert np.abs(shader.uv - oracle.uv)[both].max() < tol
    # The holes occlude as the harmonic fill does, and reflect nothing: the pixels lost
    # are exactly those whose first hit on the filled map lands in a hole cell.
    whole = tracer.trace(filled, ("uv", "mask"))
    _, points, _, valid = tracer.first_hit(filled, *_camera_rays(filled))
    in_hole = valid & ~holed.active.surface.measured(holed, points[..., 0], points[..., 2])
    assert in_hole.sum() >= 10
    assert np.array_equal(oracle.mask, whole.mask & ~in_hole)
    assert not shader.mask[in_hole].any()
    kept = oracle.mask
    assert np.array_equal(oracle.uv[kept], whole.uv[kept])
    assert np.isnan(shader.uv[~shader.mask]).all()


def _camera_rays(scene):
    origins, dirs = scene.active.camera.sample_rays(scene, None, None, 1)
    return origins[:, :, 0], dirs[:, :, 0]


def test_an_x3p_with_unmeasured_points_renders(renderer, tmp_path):
    import x3pio

    _, heights = _holed_map(tmp_path / "holed.npy")
    x3pio.write(tmp_path / "holed.x3p", heights * 1e-3, x_scale=0.4e-3, y_scale=0.4e-3)
    scene = (
        paper_scene(theta_deg=40.0)
        .with_size(24)
        .updated(surface={"kind": "heightmap", "file": str(tmp_path / "holed.x3p")})
    )
    grid = grid_of(scene)
    assert grid.spacing == pytest.approx((0.4, 0.4))
    assert scene.active.surface.nan_fraction(scene) == np.isnan(heights).sum() / heights.size
    shader = renderer.render(scene, ("uv", "mask"))
    oracle = tracer.trace(scene, ("uv", "mask"))
    assert (shader.mask != oracle.mask).sum() <= 2 and shader.mask.sum() > 100
    assert np.isfinite(grid.heights).all()  # the geometry the holes occlude with


def test_fills_give_finite_maps_and_the_harmonic_fill_keeps_a_plane(tmp_path):
    rows, cols = np.mgrid[0:14, 0:17].astype(float)
    plane = 0.013 * cols - 0.021 * rows + 0.5
    holed = plane.copy()
    holed[4:9, 5:11] = np.nan  # a hole inside the map
    holed[7, 2] = np.nan
    assert np.abs(fill_harmonic(holed) - plane).max() < 1e-9
    near = fill_nearest(holed)
    assert np.isfinite(near).all() and np.array_equal(
        near[~np.isnan(holed)], plane[~np.isnan(holed)]
    )
    assert near[7, 2] in (plane[6, 2], plane[8, 2], plane[7, 1], plane[7, 3])
    holed[0, :6] = np.nan  # at the edge too: finite, within the measured range
    filled = fill_harmonic(holed)
    assert np.isfinite(filled).all()
    assert np.nanmin(holed) <= filled.min() and filled.max() <= np.nanmax(holed)
    # through the scene: every fill is a finite map with no holes left
    np.save(tmp_path / "p.npy", holed)
    for fill in ("nearest", "harmonic"):
        grid = grid_of(_map_scene(paper_scene(), str(tmp_path / "p.npy"), 0.5, fill=fill))
        assert np.isfinite(grid.heights).all() and not grid.holes.any()
        assert grid.nan_fraction == np.isnan(holed).sum() / holed.size


def test_nan_fraction_is_the_share_of_unmeasured_samples(tmp_path):
    heights = np.zeros((30, 40))
    heights[2:5, 3:10] = np.nan  # 21 of 1200 samples, far from the dent
    np.save(tmp_path / "m.npy", heights)
    scene = _map_scene(paper_scene(), str(tmp_path / "m.npy"), 1.0)
    assert scene.active.surface.nan_fraction(scene) == 21 / 1200
    assert scene.active.surface.coverage(scene) == MapCoverage(21 / 1200, False, False)
    np.save(tmp_path / "full.npy", np.zeros((30, 40)))
    full = _map_scene(paper_scene(), str(tmp_path / "full.npy"), 1.0)
    assert full.active.surface.nan_fraction(full) == 0.0
    assert full.active.surface.coverage(full) == MapCoverage(0.0, False, False)


def test_coverage_flags_holes_near_the_dent_and_a_dent_at_the_edge(tmp_path):
    """A 41 x 41 map, 1 mm apart, centred on the origin (x, z in [-20, 20]); the dent has
    sigma = 2 mm: its region is the disc of radius 6 mm around (x0, z0)."""
    heights = np.zeros((41, 41))
    heights[20, 28] = np.nan  # x = 8, z = 0: its cells reach x = 6 (footprint: 2 cells)
    np.save(tmp_path / "m.npy", heights)
    scene = _map_scene(paper_scene(), str(tmp_path / "m.npy"), 1.0).updated(
        defect={"sigma2": 4.0, "x0": 0.0, "z0": 0.0}
    )
    surface = scene.active.surface
    cover = surface.coverage(scene)
    assert cover == MapCoverage(1 / 41**2, True, False)
    further = scene.updated(defect={"x0": -0.5})  # the hole's cells now 6.5 mm away
    assert surface.coverage(further) == MapCoverage(1 / 41**2, False, False)
    # elongated along x: 3 sqrt(4.84) = 6.6 mm reaches the cells 6.5 mm away
    along = {"x0": -0.5, "sigma_x2": 4.84, "sigma_z2": 1.0, "sigma_xz": 0.0}
    assert surface.coverage(scene.updated(defect=along)).nan_near_dent
    across = {"x0": -0.5, "sigma_x2": 1.0, "sigma_z2": 4.84, "sigma_xz": 0.0}
    assert not surface.coverage(scene.updated(defect=across)).nan_near_dent
    assert not surface.coverage(scene.updated(surface={"fill": "harmonic"})).nan_near_dent
    assert not surface.coverage(scene.updated(defect={"dmax": 0.0})).nan_near_dent
    # the map's edge: x = 20; the region reaches it from x0 = 14 on
    assert surface.coverage(scene.updated(defect={"x0": 13.9, "z0": -10.0})) == MapCoverage(
        1 / 41**2, False, False
    )
    assert surface.coverage(scene.updated(defect={"x0": 14.0, "z0": -10.0})).dent_at_edge
    assert surface.coverage(scene.updated(defect={"x0": -10.0, "z0": -25.0})).dent_at_edge
    flat = scene.updated(defect={"x0": -10.0, "z0": 16.0}, surface={"outside": "flat"})
    assert surface.coverage(flat).dent_at_edge
    # analytic surfaces have no map: the generic hook answers None
    assert paper_scene().active.surface.coverage(paper_scene()) is None


def test_only_a_map_with_holes_asks_base_measured(renderer, tmp_path):
    """The hole test is composed only for a map that has holes left (fill = "none"); its
    program keeps the uniforms it is given and the contract's code checks hold."""
    from tests.test_components import OUTPUT_SETS, check_absent_code

    from glshade.gpu.compose import ShaderFeatures, compose
    from glshade.gpu.renderer import RootSolver, scene_uniforms

    file, _ = _holed_map(tmp_path / "holed.npy")
    base = paper_scene(theta_deg=40.0).with_size(12)
    for fill, holes in (("none", True), ("nearest", False), ("harmonic", False)):
        scene = _map_scene(base, file, 0.4, fill=fill)
        for outputs in OUTPUT_SETS:
            features = ShaderFeatures.from_scene(scene, outputs)
            assert ("if (!base_measured(p))" in compose(features)[1]) == holes, (fill, outputs)
            check_absent_code(scene, outputs)
            program = renderer.program(features)
            active = {n for n in program if hasattr(program[n], "value") and n.startswith("u_")}
            assert active <= set(scene_uniforms(scene, RootSolver(), features))


def test_a_map_of_one_height_renders_in_float32(tmp_path, renderer):
    """Every sample 0: the bracketing slab has no thickness, which float32 once found empty
    (no pixel hit). It must render as the flat plate does where the map covers it."""
    np.save(tmp_path / "zero.npy", np.zeros((121, 121)))
    scene = (
        Scene()
        .with_values(
            [
                ("surface.kind", "heightmap"),
                ("surface.file", str(tmp_path / "zero.npy")),
                ("surface.spacing", (0.2, 0.2)),
                ("camera.theta_deg", 45.0),
            ]
        )
        .with_size(64)
    )
    frame = renderer.render(scene, ("uv", "mask"))
    flat = renderer.render(scene.with_value("surface.kind", "flat"), ("uv", "mask"))
    assert frame.mask.sum() > 1000
    both = frame.mask & flat.mask
    assert both.sum() == frame.mask.sum()
    np.testing.assert_allclose(frame.uv[both], flat.uv[both], atol=5e-4)


# ------------------------------------------------------------------ ranges and memory
def test_blocks_give_what_one_pass_gives(monkeypatch):
    """The bounds and the texture are computed in row blocks (no temporary of the map's
    size): blocks of one row and of a few give exactly what one block gives."""
    from glshade.components.surface import heightmap

    heights = np.random.default_rng(8).normal(size=(23, 17))
    holes = np.random.default_rng(9).uniform(size=(22, 16)) > 0.8
    whole = (map_bounds(heights, (0.3, 0.7)), split_texture(heights, holes))
    for block in (1, 17, 50, 17 * 23 - 1):
        monkeypatch.setattr(heightmap, "BLOCK_SAMPLES", block)
        assert map_bounds(heights, (0.3, 0.7)) == whole[0]
        assert np.array_equal(split_texture(heights, holes), whole[1])
    high, low = whole[1][..., 0], whole[1][..., 1]
    assert np.abs(high.astype(np.float64) + low - heights).max() < 1e-14 * np.abs(heights).max()


@pytest.mark.parametrize(
    "values, fragment",
    [
        ({"spacing": (1e-6, 1e3)}, None),
        ({"spacing": (9.9e-7, 1.0)}, "surface.spacing: must be two numbers [dx, dz] in [1e-06, "),
        ({"spacing": (1.0, 1001.0)}, "mm, got 1001.0"),
        ({"origin": (-1e4, 1e4)}, None),
        ({"origin": (0.0, 10001.0)}, "surface.origin: must be two numbers [x, z] in [-10000, "),
        ({"scale": -1e3}, None),
        ({"scale": 1e-9}, None),
        ({"scale": 9e-10}, "surface.scale: must be a number whose magnitude is in [1e-09, 1000]"),
        ({"scale": 1001.0}, "surface.scale: must be a number whose magnitude is in [1e-09, 1000]"),
    ],
)
def test_spacing_origin_and_scale_ranges(tmp_path, values, fragment):
    np.save(tmp_path / "m.npy", np.ones((8, 8)))
    surface = {"kind": "heightmap", "file": str(tmp_path / "m.npy"), "spacing": (1.0, 1.0)}
    if fragment is None:
        assert paper_scene().updated(surface={**surface, **values}).surface.file
        return
    with pytest.raises(SceneError) as info:
        paper_scene().updated(surface={**surface, **values})
    assert fragment in str(info.value) and "\n" not in str(info.value)


def test_a_harmonic_fill_beyond_the_memory_budget_is_refused(tmp_path, monkeypatch):
    """48 x 48 samples, all but one unmeasured: 2303 unknowns at 2048 bytes need 4.6 MiB;
    with a budget of 4 MiB the fill (which "none" needs too) is refused before solving,
    and "nearest" goes through."""
    heights = np.full((48, 48), np.nan)
    heights[5, 5] = 1.0
    np.save(tmp_path / "m.npy", heights)
    monkeypatch.setenv("GLSHADE_MEMORY_BUDGET_MB", "4")
    for fill in ("none", "harmonic"):
        with pytest.raises(SceneError) as info:
            grid_of(_map_scene(paper_scene(), str(tmp_path / "m.npy"), 1.0, fill=fill))
        assert str(info.value).startswith('surface.fill: must be "nearest" for this map')
        assert "at most 1985 with this map; m.npy has 2303, 4.62 MiB with the map)" in str(
            info.value
        )
    grid = grid_of(_map_scene(paper_scene(), str(tmp_path / "m.npy"), 1.0, fill="nearest"))
    assert (grid.heights == 1.0).all()


def test_maps_at_the_edges_of_the_ranges_render_without_a_warning(tmp_path):
    """Heights of ±1000 mm, spacings of 1e-6 and 1000 mm, an origin 10 m away, NaN holes
    (masked, and filled harmonically): each renders, and nothing reaches stderr (NumPy's
    overflow warnings once did, from scale = 1e308)."""
    x = np.linspace(-1.0, 1.0, 40)
    heights = np.outer(x, x)
    heights[10:15, 20:30] = np.nan
    np.save(tmp_path / "holed.npy", heights)
    scenes = {
        "fine.toml": 'spacing = [1e-6, 1e-6]\nscale = 1000\noutside = "flat"',
        "coarse.toml": 'spacing = [1000, 1000]\nscale = -1000\nfill = "harmonic"\n'
        "origin = [-10000, 10000]",
    }
    for name, lines in scenes.items():
        (tmp_path / name).write_text(
            f'[surface]\nkind = "heightmap"\nfile = "holed.npy"\n{lines}\n'
        )
        result = subprocess.run(
            [sys.executable, "-m", "glshade", "render", name, "--size", "16", "-o", "out.png"],
            capture_output=True,
            text=True,
            cwd=tmp_path,
            timeout=120,
        )
        assert result.returncode == 0 and result.stderr == "", result.stderr
        assert (tmp_path / "out.png").is_file()
        (tmp_path / "out.png").unlink()
