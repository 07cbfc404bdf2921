"""The interactive viewer: its model without a display, and the real window under Xvfb
(skipped, with the reason, where no display can be made or the viewer extra is missing)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

from glshade.app.viewer import (
    ViewerModel,
    apply_setting,
    geometry_key,
    parse_sets,
    readout_lines,
)
from glshade.errors import GlshadeError, SceneError
from glshade.files import read_png
from glshade.gpu.renderer import render
from glshade.measure.single import measure
from glshade.metrics.visibility import Visibility
from glshade.scene import paper_scene

SIZE = 96


# --------------------------------------------------------------------------- model
def test_controls_clamp_and_validate():
    scene = paper_scene().with_size(SIZE)
    # a slider drag stays in the slider's range; a typed value is validated as render does
    assert apply_setting(scene, "theta", 95.0, slider=True).camera.theta_deg == 89.5
    assert apply_setting(scene, "theta", -3.0, slider=True).camera.theta_deg == 0.5
    assert apply_setting(scene, "supersample", 40, slider=True).render.supersample == 8
    assert (
        apply_setting(scene, "theta", 89.7).camera.theta_deg == 89.7
    )  # beyond the slider, within render's range
    with pytest.raises(SceneError, match=r"camera.theta_deg: must be in \(0, 90\) degrees, got 95"):
        apply_setting(scene, "theta", 95.0)
    # the covariance stays positive definite whatever the slider says
    full = apply_setting(apply_setting(scene, "sigma_z2", 1.0), "sigma_xz", 100.0, slider=True)
    assert full.defect.sigma_xz**2 < full.defect.sigma_x2 * full.defect.sigma_z2
    # the radius keeps its sign (concave is a checkbox)
    bowl = apply_setting(apply_setting(scene, "surface", "sphere"), "concave", True)
    assert apply_setting(bowl, "radius", 30.0).surface.radius == -30.0
    with pytest.raises(GlshadeError, match="unknown setting"):
        apply_setting(scene, "zoom", 2.0)


def test_model_rejects_what_the_scene_rejects():
    model = ViewerModel(paper_scene().with_size(SIZE))
    before = model.scene
    assert not model.set("surface", "torus")
    assert model.scene == before and model.refused.startswith(
        "refused: surface.kind: must be one of"
    )
    assert not model.set("theta", 95.0)  # the panel shows why, in render's words
    assert model.refused == "refused: camera.theta_deg: must be in (0, 90) degrees, got 95.0"
    assert model.set("theta", 30.0) and model.refused == ""


def test_parse_sets():
    scene, extra = parse_sets(
        ["theta=5", "surface=sphere", "view=overlay", "animate=1"], paper_scene()
    )
    assert scene.camera.theta_deg == 5.0 and scene.surface.kind == "sphere"
    assert extra == {"view": "overlay", "animate": "1"}
    for bad, fragment in (
        ("theta", "expected name=value"),
        ("theta=abc", "a number in degrees"),
        ("view=movie", "--set view"),
        ("theta=nan", "finite"),
        ("theta=120", r"camera.theta_deg: must be in \(0, 90\) degrees"),
        ("camera.distance=-1", "camera.distance"),
    ):
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
    model.traced(
        render(scene, ("uv",)).uv, render(scene.without_defect(), ("uv",)).uv[..., 1].copy()
    )
    rgba = model.overlay_rgba()
    assert (
        rgba.shape == (256, 256, 4) and (rgba[..., 0] == 255).any() and (rgba[..., 2] == 255).any()
    )
    assert readout_lines(model.readout)[0].endswith("...")  # nothing measured yet
    model.start_metrics()
    model.wait_for_metrics()
    r = model.readout
    # the continuous limit and the deflection at 256 px: the closed form scaled (18 / 4 px)
    assert r.continuous_px == pytest.approx(18.0 / 4, rel=0.05)
    assert r.deflection_px == pytest.approx(18.0 / 4, rel=0.05)
    # the paper's number at the phase shown (0 mm, one of the sweep's phases), and over the sweep
    assert r.phase_for == (model.traces, 0.0)
    assert r.at_phase_px is not None and 0 < r.at_phase_px <= r.visibility_px
    assert r.best_phase_mm is not None and r.folded is not None and r.islands is not None
    assert not any("..." in line for line in readout_lines(r))
    colour, top = model.displacement_rgba()
    assert top == pytest.approx(r.deflection_px) and colour[..., :3].any()
    assert "u " in model.hover(128, 128) and "displacement" in model.hover(128, 128)
    assert model.hover(-1, 5) == ""
    model.close()


class _RecordingPool(ThreadPoolExecutor):
    """The model's worker pool, recording every job it is given."""

    def __init__(self):
        super().__init__(max_workers=2)
        self.jobs = []

    def submit(self, fn, /, *args, **kwargs):
        job = super().submit(fn, *args, **kwargs)
        self.jobs.append(job)
        return job


def test_render_loop_schedule_fills_the_readout_and_drops_no_finished_job():
    """The old bug: the render loop replaced a finished job with a new one every frame
    before anyone read it, so with the phase animated the readout stayed "..." for ever.
    Here the loop runs as the window's does (collect, then start, the phase moving every
    frame) and every job is checked: a finished one is taken at the next collect and its
    numbers reach the readout; one in flight is never replaced."""
    scene = paper_scene("flat", 45.0, 1.0, 0.005).with_size(128).updated(emitter={"period": 4.0})
    model = ViewerModel(scene, animate=True)
    model.traced(
        render(scene, ("uv",)).uv, render(scene.without_defect(), ("uv",)).uv[..., 1].copy()
    )
    pool = model._pool = _RecordingPool()
    phases_taken = set()
    deadline = time.monotonic() + 120.0  # a bound on a stuck worker, not a timing assertion
    iterations = 0
    while iterations < 300 or (model.readout.visibility_px is None or len(phases_taken) < 3):
        if time.monotonic() > deadline:
            break
        iterations += 1
        phase = model.scene.emitter.phase
        model.advance(0.01)  # the animation moves the phase every frame
        assert model.scene.emitter.phase != phase and not model.needs_trace
        slots = (model._case_job, model._phase_job)
        finished = [job is not None and job.done() for job in slots]
        model.collect_metrics()
        after = (model._case_job, model._phase_job)
        for job, was_done, now in zip(slots, finished, after, strict=False):
            if was_done:
                assert now is None  # taken, not left behind or replaced
            if job is not None and now is None:
                assert job.done()  # only a finished job leaves its slot
        case, phase_job = slots
        if finished[0] or (case is not None and after[0] is None):
            _, result, error = case.result()
            assert error is None and model.readout.visibility_px == result.visibility_px
            assert model.readout.deflection_px == result.deflection_px
        if finished[1] or (phase_job is not None and after[1] is None):
            key, result, error = phase_job.result()
            assert error is None and model.readout.phase_for == key
            assert model.readout.at_phase_px == result.distance_px
            phases_taken.add(key[1])
        model.start_metrics()
        for old, new in zip(after, (model._case_job, model._phase_job), strict=False):
            assert old is None or new is old  # a job in flight is never replaced
        time.sleep(0.002)
    # the loop alone (no wait) filled the readout, and it followed the animation
    assert model.readout.visibility_px is not None and model.readout.at_phase_px is not None
    assert model.readout.continuous_px is not None and model.readout.deflection_px is not None
    assert len(phases_taken) >= 3
    assert not any("..." in line for line in readout_lines(model.readout))
    # one whole-case job per trace; the phase jobs never pile up
    model.wait_for_metrics()
    whole_case = [job for job in pool.jobs if isinstance(job.result()[1], Visibility)]
    assert len(whole_case) == 1 and len(pool.jobs) - 1 <= iterations
    model.close()


def test_metric_refusal_is_shown_not_raised():
    """The period slider goes below the metric's 0.25 mm phase step: the metric refuses
    the scene, and the viewer says why instead of dying in the render loop."""
    scene = apply_setting(paper_scene().with_size(SIZE), "period", 0.2)
    model = ViewerModel(scene, view="overlay")
    model.traced(
        render(scene, ("uv",)).uv, render(scene.without_defect(), ("uv",)).uv[..., 1].copy()
    )
    model.start_metrics()
    model.wait_for_metrics()
    assert model.readout.error is not None and "step" in model.readout.error
    lines = readout_lines(model.readout)
    assert lines[0].endswith(": -") and lines[-1].startswith("not measured: step")
    model.start_metrics()
    assert model._case_job is None and model._phase_job is None  # nothing resubmitted
    assert model.overlay_rgba().shape == (SIZE, SIZE, 4)
    model.set("period", 2.0)  # a geometry the metric accepts measures again
    model.traced(
        render(model.scene, ("uv",)).uv,
        render(model.scene.without_defect(), ("uv",)).uv[..., 1].copy(),
    )
    model.start_metrics()
    model.wait_for_metrics()
    assert model.readout.error is None and model.readout.deflection_px is not None
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
    command = [sys.executable, "-m", "glshade", "view", *args]
    if not os.environ.get("DISPLAY"):
        command = ["xvfb-run", "-a", "-s", "-screen 0 1280x1024x24", *command]
    return subprocess.run(command, capture_output=True, text=True, timeout=timeout)


def screenshot(tmp_path, name, *sets):
    path = tmp_path / name
    result = view(
        "--size", "256", "--frames", "6", "--screenshot", str(path), *[f"--set={s}" for s in sets]
    )
    assert result.returncode == 0, result.stderr[-3000:]
    pixels = read_png(path)
    return (
        pixels[:256, :256, 0].astype(np.float64) / 255.0
    )  # the image sits at the window's top left


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


@needs_display
def test_scripted_run_ends_with_the_measured_readout():
    """A few hundred frames with the phase animated and the panel drawn: the readout line
    has numbers (the worker's results reached the window), the same as glshade.measure's
    for the scene."""
    result = view(
        "--size",
        "128",
        "--frames",
        "300",
        "--set",
        "theta=45",
        "--set",
        "sigma2=1",
        "--set",
        "period=4",
        "--set",
        "animate=1",
    )
    assert result.returncode == 0, result.stderr[-3000:]
    lines = [line for line in result.stdout.splitlines() if line.startswith("readout: ")]
    assert len(lines) == 1, result.stdout
    line = lines[0]
    number = r"(\d+(?:\.\d+)?) px"
    at_phase = re.search(r"visibility, this phase: " + number, line)
    best = re.search(r"visibility, best phase: " + number, line)
    continuous = re.search(r"continuous limit: " + number, line)
    moved = re.search(r"deflection: " + number, line)
    assert at_phase and best and continuous and moved, line
    assert "..." not in line
    scene = paper_scene("flat", 45.0, 1.0, 0.005).with_size(128).updated(emitter={"period": 4.0})
    truth = measure(scene)
    assert float(best.group(1)) == truth.visibility_px > 0
    assert float(continuous.group(1)) == round(truth.visibility_continuous_px, 2)
    assert float(moved.group(1)) == round(truth.deflection_px, 2)


def test_bad_scene_file_opens_nothing(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[camera]\ntheta_deg = 120.0\n")
    result = subprocess.run(
        [sys.executable, "-m", "glshade", "view", str(bad), "--frames", "1"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2
    assert (
        result.stderr.strip()
        == "glshade: error: camera.theta_deg: must be in (0, 90) degrees, got 120.0"
    )
    result = subprocess.run(
        [sys.executable, "-m", "glshade", "view", "--set", "theta=abc"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert (
        result.returncode == 2 and "camera.theta_deg: must be a number in degrees" in result.stderr
    )


def test_formulas_and_files_are_text_fields(tmp_path):
    from glshade.app.viewer.controls import panel_params

    model = ViewerModel(paper_scene().with_size(SIZE).with_value("surface.kind", "formula"))
    assert "surface.expression" in {p.path for p in panel_params(model.scene)}
    assert model.set_value("surface.expression", "0.001*x^2")
    assert model.scene.surface.expression == "0.001*x^2"
    assert not model.set_value("surface.expression", "x; y")
    assert model.refused.startswith("refused: surface.expression: ';' at column 2 is not allowed")
    assert model.scene.surface.expression == "0.001*x^2"
