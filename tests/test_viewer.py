"""The interactive viewer: its model without a display, and the real window under Xvfb
(skipped, with the reason, where no display can be made or the viewer extra is missing)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from glshade.errors import GlshadeError
from glshade.files import read_png
from glshade.renderer import render
from glshade.scene import paper_scene
from glshade.viewer import ViewerModel, apply_setting, geometry_key, parse_sets

SIZE = 96


# --------------------------------------------------------------------------- model
def test_controls_clamp_and_validate():
    scene = paper_scene().with_size(SIZE)
    assert apply_setting(scene, "theta", 95.0).camera.theta_deg == 89.5  # clamped to the slider
    assert apply_setting(scene, "theta", -3.0).camera.theta_deg == 0.5
    assert apply_setting(scene, "supersample", 40).render.supersample == 8
    # the covariance stays positive definite whatever the slider says
    full = apply_setting(apply_setting(scene, "sigma_z2", 1.0), "sigma_xz", 100.0)
    assert full.defect.sigma_xz ** 2 < full.defect.sigma_x2 * full.defect.sigma_z2
    # the radius keeps its sign (concave is a checkbox)
    bowl = apply_setting(apply_setting(scene, "surface", "sphere"), "concave", True)
    assert apply_setting(bowl, "radius", 30.0).surface.radius == -30.0
    with pytest.raises(GlshadeError, match="unknown setting"):
        apply_setting(scene, "zoom", 2.0)


def test_model_rejects_what_the_scene_rejects():
    model = ViewerModel(paper_scene().with_size(SIZE))
    before = model.scene
    assert not model.set("surface", "torus")
    assert model.scene == before


def test_parse_sets():
    scene, extra = parse_sets(["theta=5", "surface=sphere", "view=overlay", "animate=1"], paper_scene())
    assert scene.camera.theta_deg == 5.0 and scene.surface.kind == "sphere"
    assert extra == {"view": "overlay", "animate": "1"}
    for bad, fragment in (("theta", "expected name=value"), ("theta=abc", "expected a number"),
                          ("view=movie", "--set view"), ("theta=nan", "finite")):
        with pytest.raises(GlshadeError, match=fragment):
            parse_sets([bad], paper_scene())


def test_phase_change_reshades_geometry_change_retraces():
    model = ViewerModel(paper_scene().with_size(SIZE))
    scene = model.scene
    frame = render(scene, ("uv",))
    normal = render(scene.without_defect(), ("uv",))
    model.traced(frame.uv, normal.uv[..., 1].copy())
    assert not model.needs_trace
    model.animate = True
    model.advance(0.3)
    assert model.scene.emitter.phase > 0 and not model.needs_trace  # a phase change: no re-trace
    model.set("dmax", 0.01)
    assert model.needs_trace
    assert geometry_key(model.scene.with_phase(1.0)) == geometry_key(model.scene)


def test_model_pictures_metrics_and_hover():
    scene = paper_scene("flat", 45.0, 1.0, 0.005).with_size(256)
    model = ViewerModel(scene)
    model.traced(render(scene, ("uv",)).uv, render(scene.without_defect(), ("uv",)).uv[..., 1].copy())
    rgba = model.overlay_rgba()
    assert rgba.shape == (256, 256, 4) and (rgba[..., 0] == 255).any() and (rgba[..., 2] == 255).any()
    model.start_metrics()
    model._continuous.result()
    model._pending.result()
    model.collect_metrics()
    # the continuous metric at 256 px: the closed form scaled (18 / 4 px)
    assert model.readout.continuous_px == pytest.approx(18.0 / 4, rel=0.05)
    assert model.readout.visibility_px is not None
    colour, top = model.displacement_rgba()
    assert top == pytest.approx(model.readout.continuous_px) and colour[..., :3].any()
    assert "u " in model.hover(128, 128) and "displacement" in model.hover(128, 128)
    assert model.hover(-1, 5) == ""
    model.close()


# --------------------------------------------------------------------------- window
def _viewer_available() -> str | None:
    try:
        import imgui_bundle  # noqa: F401
        import moderngl_window  # noqa: F401
    except ImportError as exc:
        return f"the viewer extra is not installed ({exc.name})"
    if not os.environ.get("DISPLAY") and shutil.which("xvfb-run") is None:
        return "no display and no xvfb-run to make one (Debian package xvfb)"
    return None


needs_display = pytest.mark.skipif(_viewer_available() is not None, reason=str(_viewer_available()))


def view(*args, timeout=180):
    command = [sys.executable, "-m", "glshade.cli", "view", *args]
    if not os.environ.get("DISPLAY"):
        command = ["xvfb-run", "-a", "-s", "-screen 0 1280x1024x24", *command]
    return subprocess.run(command, capture_output=True, text=True, timeout=timeout)


def screenshot(tmp_path, name, *sets):
    path = tmp_path / name
    result = view("--size", "256", "--frames", "6", "--screenshot", str(path), *[f"--set={s}" for s in sets])
    assert result.returncode == 0, result.stderr[-3000:]
    pixels = read_png(path)
    return pixels[:256, :256, 0].astype(np.float64) / 255.0  # the image sits at the window's top left


@needs_display
def test_window_shows_the_scene_as_the_batch_renderer_does(tmp_path):
    shown = screenshot(tmp_path, "a.png", "theta=30", "sigma2=1")
    scene = paper_scene("flat", 30.0, 1.0, 0.005).with_size(256)
    offscreen = np.clip(render(scene).image, 0, 1)
    assert shown.std() > 0.2  # stripes, not a blank window
    assert np.abs(shown - offscreen).mean() < 2 / 255 and np.abs(shown - offscreen).max() <= 4 / 255
    # the dent's distortion is there: the defect-free render differs at the centre only
    plain = np.clip(render(scene.without_defect()).image, 0, 1)
    centre = slice(108, 148)
    assert np.abs(shown - plain)[centre, centre].max() > 0.3
    assert np.abs(shown - plain)[:40].max() < 4 / 255


@needs_display
def test_changing_a_parameter_changes_the_frame(tmp_path):
    a = screenshot(tmp_path, "a.png", "theta=45")
    b = screenshot(tmp_path, "b.png", "theta=45", "phase=0.5")
    c = screenshot(tmp_path, "c.png", "theta=45", "surface=cylinder")
    # (theta alone would hardly do on a flat mirror: its stripe spacing in the image does
    # not depend on theta, only the dent's footprint does)
    assert np.abs(a - b).mean() > 0.1 and np.abs(a - c).mean() > 0.05


@needs_display
def test_phase_animation_never_retraces():
    result = view("--size", "128", "--frames", "20", "--benchmark", "phase", "--no-panel")
    assert result.returncode == 0, result.stderr[-3000:]
    assert "(1 traces, 20 re-shades)" in result.stdout
    result = view("--size", "128", "--frames", "10", "--benchmark", "theta", "--no-panel")
    assert "(10 traces" in result.stdout


def test_bad_scene_file_opens_nothing(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[camera]\ntheta_deg = 120.0\n")
    result = subprocess.run([sys.executable, "-m", "glshade.cli", "view", str(bad), "--frames", "1"],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2
    assert result.stderr.strip() == "glshade: error: camera.theta_deg: must be in (0, 90) degrees, got 120.0"
    result = subprocess.run([sys.executable, "-m", "glshade.cli", "view", "--set", "theta=abc"],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2 and "--set theta: expected a number" in result.stderr
