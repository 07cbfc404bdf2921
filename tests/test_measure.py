"""Measuring one scene: ``glshade measure`` (SPEC §8.3), ``glshade.measure`` and the
viewer, which all report the same three numbers (SPEC §6) for the same scene."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import glshade
from glshade.app.viewer import ViewerModel
from glshade.files import read_png
from glshade.gpu.renderer import Renderer
from glshade.instruments.record import Measurement
from glshade.instruments.stripes.single import measure_scene
from glshade.scene import paper_scene

KEYS = (
    "visibility_px",
    "visibility_continuous_px",
    "deflection_px",
    "folded",
    "islands",
    "best_phase_mm",
)
FOLDING = ["--surface", "flat", "--theta", "5", "--sigma2", "1", "--dmax", "0.005"]


def cli(*args, cwd=None):
    return subprocess.run(
        [sys.executable, "-m", "glshade", "measure", *args],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=cwd,
        check=False,
    )


def as_json(result) -> dict:
    assert result.returncode == 0, result.stderr[-3000:]
    lines = result.stdout.strip().splitlines()
    assert len(lines) == 1, result.stdout  # one object, nothing else
    return json.loads(lines[0])


def test_json_of_a_folding_dent():
    """θ 5°, σ² 1, 5 µm at 512 px: the rays move by the closed form (18 / 2 px), but the
    stripe map folds and the fold caps what a viewer sees at the band the dent occupies
    (about 5.5 px at 1024, so near 2.8 px here)."""
    out = as_json(cli(*FOLDING, "--size", "512", "--json"))
    for key in KEYS:
        assert key in out, key
    assert out["folded"] is True and out["islands"] >= 1
    assert out["deflection_px"] == pytest.approx(18.0 / 2, rel=0.05)
    assert 1.5 <= out["visibility_px"] <= 4.0
    assert out["visibility_px"] < 0.5 * out["deflection_px"]
    assert out["visibility_continuous_px"] == pytest.approx(2.8, abs=0.5)
    assert 0.0 <= out["best_phase_mm"] < 2.0 and out["size"] == [512, 512]


def test_table_and_overlay(tmp_path):
    png = tmp_path / "overlay.png"
    result = cli(*FOLDING, "--size", "256", "--overlay", str(png))
    assert result.returncode == 0, result.stderr[-3000:]
    text = result.stdout
    for name in ("visibility_px", "visibility_continuous_px", "deflection_px", "folded"):
        assert f"  {name} " in text, name
    assert "folded                    yes" in text and f"wrote {png}" in text
    numbers = {line.split()[0]: line.split()[1] for line in text.splitlines()[1:] if line.strip()}
    assert float(numbers["deflection_px"]) == pytest.approx(18.0 / 4, rel=0.05)
    pixels = read_png(png)  # a matplotlib figure: RGB or RGBA
    assert (
        pixels.ndim == 3
        and pixels.shape[0] > 100
        and pixels.shape[1] > 100
        and pixels.shape[2] in (3, 4)
    )
    assert pixels.dtype == np.uint8 and pixels.std() > 10  # a picture, not a blank
    assert sorted(p.name for p in tmp_path.iterdir()) == ["overlay.png"]  # no temporary left over


def test_python_api_gives_the_cli_numbers():
    out = as_json(cli(*FOLDING, "--size", "256", "--json"))
    result = glshade.measure(paper_scene("flat", 5.0, 1.0, 0.005).with_size(256))
    assert isinstance(result, glshade.Visibility)
    summary = Measurement.of(paper_scene("flat", 5.0, 1.0, 0.005).with_size(256), result).row()
    assert {key: summary[key] for key in KEYS} == {key: out[key] for key in KEYS}
    assert result.folded and result.visibility_px < result.deflection_px


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["missing.toml"], "scene file: must be an existing TOML file"),
        (["--theta", "95"], "--theta (camera.theta_deg): must be in (0.001, 90)"),
        (["--step", "3"], "step: must be at most one stripe period (2 mm)"),
        (["--threshold", "1.5"], "threshold: must be in (0, 1)"),
        (
            ["--overlay", "no_such_dir/overlay.png"],
            "--overlay no_such_dir/overlay.png: directory no_such_dir does not exist",
        ),
    ],
    ids=["missing-scene", "theta", "step", "threshold", "overlay-dir"],
)
def test_bad_input(tmp_path, args, fragment):
    # --device 99 names no EGL device: each error must come first, before any rendering
    result = cli("--size", "64", "--device", "99", *args, cwd=tmp_path)
    assert result.returncode == 2
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("glshade: error: "), result.stderr
    assert fragment in lines[0]
    assert result.stdout == ""
    assert list(tmp_path.iterdir()) == []  # nothing written, no directory made


def test_bad_overlay_path_fails_without_rendering(tmp_path):
    """The same without the device trap: the error, no file, no directory."""
    target = tmp_path / "missing" / "overlay.png"
    result = cli("--size", "64", "--overlay", str(target), cwd=tmp_path)
    assert result.returncode == 2 and result.stderr.count("\n") == 1
    assert result.stderr.startswith("glshade: error: --overlay ")
    assert not target.parent.exists() and list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("size, theta", [(128, 45.0), (256, 5.0)])
def test_viewer_reports_what_measure_reports(size, theta):
    scene = paper_scene("flat", theta, 1.0, 0.005).with_size(size).updated(emitter={"period": 4.0})
    with Renderer() as renderer:
        uv = renderer.render(scene, ("uv",)).uv
        v0 = np.ascontiguousarray(renderer.render(scene.without_defect(), ("uv",)).uv[..., 1])
        truth = measure_scene(renderer, scene)
    model = ViewerModel(scene)
    model.traced(uv, v0)
    model.start_metrics()
    model.wait_for_metrics()
    r = model.readout
    assert r.visibility_px == truth.visibility_px and r.visibility_px > 0
    assert r.continuous_px == truth.visibility_continuous_px
    assert r.deflection_px == truth.deflection_px
    assert (r.folded, r.islands, r.best_phase_mm) == (
        truth.folded,
        truth.islands,
        truth.best_phase_mm,
    )
    # the live comparison at phase 0 is the sweep's first phase (no registration offset here)
    assert truth.offset_px == (0, 0) and r.at_phase_px == truth.per_phase[0].distance_px
    model.close()


def test_the_python_call_writes_the_overlay_through_the_instrument(tmp_path, renderer):
    """``glshade.measure(scene, overlay=...)`` writes the stripe metric's declared
    ``--overlay`` file and measures what the call without it measures."""
    import glshade
    from glshade.files import read_png
    from glshade.scene import paper_scene

    scene = paper_scene().with_size(64)
    png = tmp_path / "overlay.png"
    drawn = glshade.measure(scene, renderer=renderer, overlay=png)
    plain = glshade.measure(scene, renderer=renderer)
    assert drawn.visibility_px == plain.visibility_px and drawn.status == plain.status
    assert read_png(png).shape[:2][0] > 0
