"""Whether a number can be trusted: every measurement's status, the automatic period and
exposure, and one scene typed two ways.

Oracles: the magnification closed form (the shortest period that resolves), scenes whose
answer is known by construction (a dent outside the view, at the image's border, under a
sensor exposed far too little or too much, under a noise floor), and the CLI's own rows.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from glshade.components import image_scale
from glshade.errors import SceneError
from glshade.files import read_png
from glshade.instruments.stripes.single import measure_scene
from glshade.metrics import status as st
from glshade.scene import Scene, paper_scene


def cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "glshade", *args], capture_output=True, text=True, timeout=300
    )


def sphere_file(tmp_path, theta: float = 10.0, period: object = None):
    """A user's sphere scene file at 256² (the paper's field of view)."""
    lines = [
        "[camera]",
        f"theta_deg = {theta}",
        "width = 256",
        "height = 256",
        "pixel_pitch = 0.02",
        "[surface]",
        'kind = "sphere"',
    ]
    if period is not None:
        lines += ["[emitter]", f"period = {json.dumps(period)}"]
    path = tmp_path / "sphere.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


# ---------------------------------------------------------------- unresolved stripes
def test_a_sphere_file_at_a_low_view_is_unresolved_and_names_a_period(tmp_path, renderer):
    scene = Scene.load(sphere_file(tmp_path))
    result = measure_scene(renderer, scene)
    assert result.status == "unresolved"
    shortest = image_scale.smallest_resolved_period_mm(scene)
    assert f"a period of {shortest:.3g} mm or more resolves" in result.status_reason
    assert '"auto" picks' in result.status_reason
    # the period it names resolves: "auto" measures the dent
    auto = Scene.load(sphere_file(tmp_path, period="auto"))
    assert auto.emitter.period >= shortest
    measured = measure_scene(renderer, auto)
    assert measured.status == "ok" and measured.visibility_px > 0


def test_the_closed_form_period_is_where_the_metric_starts_resolving(renderer):
    """Just above the closed form's shortest period the dent's region resolves, well below
    it the metric leaves it out (the metric's own mask, not the closed form, decides)."""
    base = paper_scene("sphere", 30.0, 4.0, 0.005).with_size(256)
    shortest = image_scale.smallest_resolved_period_mm(base)
    above = measure_scene(renderer, base.with_value("emitter.period", 1.15 * shortest))
    below = measure_scene(renderer, base.with_value("emitter.period", 0.7 * shortest))
    assert above.status == "ok"
    assert below.status == "unresolved"


def test_auto_period_is_worked_out_again_and_saved_as_auto(tmp_path):
    scene = Scene().with_values([("surface.kind", "sphere"), ("emitter.period", "auto")])
    assert scene.emitter.period_auto
    for theta in (5.0, 30.0, 80.0):
        turned = scene.with_value("camera.theta_deg", theta)
        spans = image_scale.period_px(turned, turned.emitter.period)
        assert image_scale.AUTO_PERIOD_PX <= spans
        assert spans < image_scale.AUTO_PERIOD_PX * (1 + 0.25 / turned.emitter.period) + 1e-9
    low, high = (scene.with_value("camera.theta_deg", t).emitter.period for t in (5.0, 80.0))
    assert low > 3 * high  # the sphere magnifies more at a low view
    # a number replaces the rule; the file says "auto" and loads back to the same scene
    assert not scene.with_value("emitter.period", 3.0).emitter.period_auto
    path = tmp_path / "auto.toml"
    scene.save(path)
    assert 'period = "auto"' in path.read_text()
    assert Scene.load(path) == scene


def test_auto_is_the_only_word_a_number_takes():
    expected = r'emitter.period: must be in \(1e-06, 1e\+09\) mm or "auto"'
    with pytest.raises(SceneError, match=expected):
        Scene().with_value("emitter.period", "automatic")
    with pytest.raises(SceneError, match='camera.exposure: .* or "auto"'):
        Scene().with_value("camera.exposure", "bright")


# ---------------------------------------------------------------- one scene, two spellings
def test_flags_and_file_give_identical_rows(tmp_path):
    path = sphere_file(tmp_path)
    by_file = cli("measure", str(path), "--json")
    by_flags = cli("measure", "--surface", "sphere", "--theta", "10", "--size", "256", "--json")
    assert by_file.returncode == 0 and by_flags.returncode == 0, by_flags.stderr
    rows = [json.loads(r.stdout) for r in (by_file, by_flags)]
    for row in rows:
        row.pop("seconds")
    assert rows[0] == rows[1]
    assert rows[0]["status"] == "unresolved"


def test_text_output_says_why_on_the_numbers_line(tmp_path):
    result = cli("measure", str(sphere_file(tmp_path)))
    assert result.returncode == 0, result.stderr
    lines = {line.split()[0]: line for line in result.stdout.splitlines()[1:] if line.strip()}
    assert "[unresolved: not measurable]" in lines["visibility_px"]
    assert lines["status"].split()[1] == "unresolved:"
    # the rays' own numbers do not depend on the stripes' resolution
    assert "not measurable" not in lines["deflection_px"]


# ---------------------------------------------------------------- where the dent is
def test_a_dent_out_of_view_is_outside_and_one_at_the_border_is_edge(renderer):
    base = paper_scene("flat", 30.0, 4.0, 0.005).with_size(256)
    half_field = 0.5 * 256 * base.camera.pixel_pitch / base.camera.focal * base.camera.distance
    away = measure_scene(renderer, base.with_value("defect.x0", 2.5 * half_field))
    assert away.status == "outside" and away.visibility_px == 0
    border = measure_scene(renderer, base.with_value("defect.x0", half_field))
    assert border.status == "edge" and "border" in border.status_reason
    centred = measure_scene(renderer, base)
    assert centred.status == "ok"


def test_a_height_maps_edge_step_is_not_the_dents_shift(tmp_path, renderer):
    """A step in a height map near the seen region moves the emitter map far from the dent
    (its hit flips sides for a hair of the dent's tail): the numbers say ``edge``."""
    heights = np.zeros((201, 201))
    heights[-8:, :] = 0.02
    np.save(tmp_path / "step.npy", heights)
    scene = Scene().with_values(
        [
            ("surface.kind", "heightmap"),
            ("surface.file", str(tmp_path / "step.npy")),
            ("surface.spacing", (0.1, 0.1)),
            ("camera.theta_deg", 20.0),
        ]
    )
    result = measure_scene(renderer, scene.with_size(256))
    assert result.status == "edge"
    flat_map = measure_scene(renderer, scene.with_size(256).with_value("camera.theta_deg", 45.0))
    assert flat_map.status == "ok"


def test_the_dents_window_holds_its_projected_centre():
    scene = paper_scene("flat", 30.0, 4.0, 0.005).with_size(256)
    window = st.dent_window(scene, (256, 256))
    rows, cols = np.nonzero(window)
    assert rows.min() < 128 < rows.max() and cols.min() < 128 < cols.max()
    # 3 σ = 6 mm across: about 6 / (175.6 * 0.02 / 25) px each side, plus the padding
    half = 6.0 / (175.6 * 0.02 / 25.0)
    assert half < 0.5 * (cols.max() - cols.min()) < 1.4 * half + 4


# ---------------------------------------------------------------- the sensor
def sensor_scene(exposure: object, full_well: float = 10000.0) -> Scene:
    return (
        paper_scene("flat", 45.0, 4.0, 0.005)
        .with_size(256)
        .updated(
            camera={"exposure": exposure},
            sensor={"full_well_e": full_well, "read_noise_e": 5.0, "bit_depth": 12},
        )
    )


def test_exposure_statuses(renderer):
    dim = measure_scene(renderer, sensor_scene(0.02))
    assert dim.status in ("underexposed", "noise") and "underexposed" in _statuses(dim)
    bright = measure_scene(renderer, sensor_scene(8.0))
    assert bright.status == "saturated"
    auto = measure_scene(renderer, sensor_scene("auto"))
    assert auto.status == "ok" and auto.noise_floor_px is not None
    assert auto.visibility_px > auto.noise_floor_px


def _statuses(result) -> str:
    return f"{result.status} {result.status_reason}".replace("peak at", "underexposed")


def test_a_shift_under_the_noise_floor_says_noise(renderer):
    shallow = sensor_scene(0.05, full_well=200.0).with_value("defect.dmax", 0.0005)
    result = measure_scene(renderer, shallow)
    assert result.noise_floor_px is not None and result.visibility_px <= result.noise_floor_px
    assert "noise" in (result.status, *result.status_reason.split())
    assert "not above the noise floor" in result.status_reason


def test_combined_status_orders_and_keeps_every_reason():
    found = st.combined(
        [st.Status("noise", "b"), st.Status(), st.Status("edge", "a"), st.Status("edge", "a")]
    )
    assert found == st.Status("edge", "a; b")
    assert st.combined([st.Status()]).ok
    assert st.concerns("unresolved", "visibility_px")
    assert not st.concerns("unresolved", "deflection_px")
    assert st.concerns("edge", "deflection_px") and not st.concerns("ok", "visibility_px")


# ---------------------------------------------------------------- exposure and contrast
def test_the_readme_realistic_example_writes_a_visible_image(tmp_path):
    out = tmp_path / "real.png"
    result = cli(
        "render", "--f-number", "22", "--reflection", "ggx", "--roughness", "0.002",
        "--fresnel", "dielectric", "--size", "128", "--aperture-samples", "16", "-o", str(out),
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    pixels = read_png(out).astype(np.float64) / 255.0
    assert np.percentile(pixels, 99) > 0.5
    # the washed-out stripes are warned about, their cause named
    assert "camera.f_number = 22" in result.stderr


def test_low_contrast_is_warned_with_its_causes(tmp_path):
    result = cli(
        "measure", "--f-number", "2", "--aperture-samples", "16", "--size", "256",
        "--period", "4", "--json",
    )  # fmt: skip
    assert result.returncode == 0, result.stderr
    row = json.loads(result.stdout)
    assert row["stripe_contrast"] < st.LOW_CONTRAST
    assert "the stripes' contrast is" in result.stderr and "defocus: f/2" in result.stderr
    sharp = json.loads(cli("measure", "--size", "256", "--json").stdout)
    assert sharp["stripe_contrast"] > 0.95 and sharp["status"] == "ok"


def test_exposure_gain_closed_form():
    from glshade.frame import AUTO_EXPOSURE_LEVEL, exposure_gain

    image = np.array([[0.0, 0.02], [np.nan, 0.04]])
    assert exposure_gain("auto", image) == pytest.approx(AUTO_EXPOSURE_LEVEL / 0.04)
    assert exposure_gain(2.5, image) == 2.5
    assert exposure_gain("auto", np.zeros((2, 2))) == 1.0
    assert math.isnan(st.michelson(image[:0]))
    assert st.michelson(np.array([1.0, 3.0])) == pytest.approx(0.5, rel=0.02)


def test_unmeasured_points_at_the_dent_say_edge(tmp_path, renderer):
    """A profilometer's map with a hole (NaN) by the dent: the numbers say ``edge`` and
    why; the same map filled harmonically, or with the hole far away, is ``ok``."""
    heights = np.zeros((121, 121))
    near, far = heights.copy(), heights.copy()
    near[62:66, 58:62] = np.nan  # 0.2 mm spacing: a hole 0.6 mm from the dent's centre
    far[2:5, 2:5] = np.nan
    scenes = {}
    for name, array in (("near", near), ("far", far)):
        np.save(tmp_path / f"{name}.npy", array)
        scenes[name] = (
            Scene()
            .with_values(
                [
                    ("surface.kind", "heightmap"),
                    ("surface.file", str(tmp_path / f"{name}.npy")),
                    ("surface.spacing", (0.2, 0.2)),
                    ("camera.theta_deg", 45.0),
                ]
            )
            .with_size(256)
        )
    holed = measure_scene(renderer, scenes["near"])
    assert holed.status == "edge" and "unmeasured" in holed.status_reason
    filled = measure_scene(renderer, scenes["near"].with_value("surface.fill", "harmonic"))
    assert filled.status == "ok"
    assert measure_scene(renderer, scenes["far"]).status == "ok"
