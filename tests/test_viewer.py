"""The interactive viewer: its model without a display, and the real window under Xvfb
(skipped, with the reason, where no display can be made or the viewer extra is missing)."""

from __future__ import annotations

import ctypes.util
import json
import os
import re
import shutil
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

import glshade
from glshade.app.viewer import (
    ViewerModel,
    apply_setting,
    geometry_key,
    parse_sets,
    readout_lines,
)
from glshade.app.viewer.colourbar import (
    NO_VALUE_RGB,
    colour_bar_layout,
    colour_bar_ticks,
    colour_index,
    colour_lut,
)
from glshade.app.viewer.instrument_view import InstrumentCase, case_lines, case_scene
from glshade.app.viewer.model import IDLE_WAIT_S, POLL_S, SETTLE_FRAMES, FrameSchedule
from glshade.errors import GlshadeError, SceneError
from glshade.files import read_png
from glshade.gpu.renderer import Renderer, render
from glshade.instruments.pmd.settings import PmdSettings
from glshade.instruments.pmd.station import measure_pmd_scene
from glshade.instruments.pmd.views import PMD_SIZE
from glshade.instruments.registry import instrument
from glshade.measure.single import measure
from glshade.metrics.visibility import Visibility
from glshade.scene import paper_scene

SIZE = 96


def pmd_scene(scene, size=PMD_SIZE):
    """The scene the viewer's PMD views measure: phase measuring's, at ``size`` px."""
    return case_scene(instrument("pmd"), geometry_key(scene), size)


def pmd_readout_lines(scene, result, size):
    """The readout of a PMD view of ``result``, measured on ``scene`` at ``size`` px."""
    pmd = instrument("pmd")
    return case_lines(pmd.views(), InstrumentCase(pmd, scene, result), False, size)


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
    with pytest.raises(
        SceneError, match=r"camera.theta_deg: must be in \(0.001, 90\) degrees, got 95"
    ):
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
    assert model.refused == "refused: camera.theta_deg: must be in (0.001, 90) degrees, got 95.0"
    assert model.set("theta", 30.0) and model.refused == ""


def test_parse_sets():
    scene, extra = parse_sets(
        ["theta=5", "surface=sphere", "view=overlay", "animate=1"], paper_scene()
    )
    assert scene.camera.theta_deg == 5.0 and scene.surface.kind == "sphere"
    assert extra == {"view": "overlay", "animate": "1"}
    _, extra = parse_sets(["view=pmd-error", "pmd_size=64"], paper_scene().with_size(128))
    assert extra == {"view": "pmd-error", "pmd_size": "64"}
    with pytest.raises(GlshadeError, match=r"--set pmd_size: must be an integer in \[16, 128\]"):
        parse_sets(["pmd_size=256"], paper_scene().with_size(128))
    for bad, fragment in (
        ("theta", "expected name=value"),
        ("theta=abc", "a number in degrees"),
        ("view=movie", "--set view"),
        ("theta=nan", "finite"),
        ("theta=120", r"--set theta \(camera.theta_deg\): must be in \(0.001, 90\) degrees"),
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
    # the picture's colours are the colour bar's: 0 px at its dark end, the top at its bright
    lut, d = colour_lut(), model.displacement
    peak = np.unravel_index(np.nanargmax(d), d.shape)
    assert (colour[peak][:3] == lut[255]).all()
    calm = np.unravel_index(np.nanargmin(d), d.shape)
    assert (colour[calm][:3] == lut[colour_index(d[calm], top)]).all()
    assert "u " in model.hover(128, 128) and "displacement" in model.hover(128, 128)
    assert model.hover(-1, 5) == ""
    model.close()


def test_colour_bar_ticks_follow_the_displacement_scale():
    """The bar's numbers: 0 and round steps up to the scale's top (the largest
    displacement, px), each at its share of the bar, labelled with its value."""
    for top in (4.55, 0.3, 1.0, 12.7, 0.0123, 100.0, 2.5, 7.0):
        ticks = colour_bar_ticks(top)
        values = [t.value for t in ticks]
        assert values[0] == 0.0 and ticks[0].at == 0.0
        assert 3 <= len(ticks) <= 6 and values[-1] <= top * (1 + 1e-9)
        step = values[1]
        assert top - values[-1] < step  # the ticks reach the top's last whole step
        mantissa = step / 10 ** np.floor(np.log10(step))
        assert any(np.isclose(mantissa, m) for m in (1, 2, 2.5, 5))
        for i, tick in enumerate(ticks):
            assert tick.value == pytest.approx(i * step)
            assert tick.at == pytest.approx(tick.value / top)
            assert float(tick.label) == pytest.approx(tick.value, abs=1e-12)
    assert [t.label for t in colour_bar_ticks(4.55)] == ["0", "1", "2", "3", "4"]
    assert [t.label for t in colour_bar_ticks(0.3)] == ["0.0", "0.1", "0.2", "0.3"]
    assert [t.label for t in colour_bar_ticks(2.5)][-1] == "2.5"
    assert [t.value for t in colour_bar_ticks(0.0)] == [0.0]  # nothing measured yet
    # beneath the image when the window leaves room, over its bottom edge otherwise
    assert not colour_bar_layout(512, 512, 600).overlaid
    low = colour_bar_layout(512, 512, 512)
    assert low.overlaid and low.strip_bottom == 512


def test_colour_bar_ticks_of_signed_and_cyclic_scales():
    """A scale symmetric about 0 (the PMD error) has 0 at its middle and ticks paired
    about it; the wrapped phase's 0 to 2π has the whole radians."""
    ticks = colour_bar_ticks(1.3, bottom=-1.3)
    assert [t.label for t in ticks] == ["-1", "0", "1"]
    for tick in ticks:
        assert tick.at == pytest.approx((tick.value + 1.3) / 2.6)
    assert [t.value for t in ticks] == [-t.value for t in reversed(ticks)]
    assert [t.label for t in colour_bar_ticks(2 * np.pi)] == ["0", "2", "4", "6"]
    # the LUT index on a shifted scale: the bottom at 0, the middle at the middle
    assert colour_index(np.array([-1.3, 0.0, 1.3]), 1.3, -1.3).tolist() == [0, 127, 255]


def test_idle_schedule_draws_only_on_change():
    """The window's loop draws what the schedule asks for: a few frames after an event,
    every frame of an animation or a scripted run, a frame when the worker hands in a
    result; nothing at all for an untouched window."""
    scene = paper_scene("flat", 45.0, 1.0, 0.005).with_size(64).updated(emitter={"period": 4.0})
    model = ViewerModel(scene)
    schedule = FrameSchedule()
    assert model.needs_trace and schedule.wants_frame(model)  # the first frames: trace
    model.traced(render(scene, ("uv",)).uv, render(scene.without_defect(), ("uv",)).uv[..., 1])
    drawn = 0
    while schedule.wants_frame(model):  # the window's loop, minus the window
        model.start_metrics()
        schedule.drew()
        drawn += 1
        assert drawn <= SETTLE_FRAMES + 1
        if schedule.owed == 0:  # the loop would wait now; the worker finishes meanwhile
            for job in (model._case_job, model._phase_job):
                if job is not None:
                    job.result()
    assert model.readout.deflection_px is not None and not model.metrics_pending
    # settled: a thousand turns of the loop draw nothing, and it waits long between them
    assert not any(schedule.wants_frame(model) for _ in range(1000))
    assert schedule.wait_s(model) == IDLE_WAIT_S
    schedule.poke()  # an input event
    turns = 0
    while schedule.wants_frame(model):
        schedule.drew()
        turns += 1
    assert turns == SETTLE_FRAMES
    model.set("phase", 1.0)  # a phase change: the worker measures, the loop polls for it
    model.start_metrics()
    assert model.metrics_pending and schedule.wait_s(model) == POLL_S
    model._phase_job.result()
    assert schedule.wants_frame(model)  # the result arrived: one frame shows it
    assert not schedule.wants_frame(model)
    model.animate = True
    assert all(schedule.wants_frame(model) for _ in range(10))
    model.animate = False
    assert FrameSchedule(continuous=True).wants_frame(model)  # a scripted run draws on
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


def test_pmd_view_measures_once_per_change_in_its_own_thread():
    """A PMD view: the station measures the scene (the fringes on its screen, at the PMD
    size) in its own thread, with the numbers measure_pmd_scene gives for that scene;
    the phase, another PMD map or a rest submit nothing; a new dent does; the image
    view shows the paper's readout again."""
    scene = paper_scene("flat", 45.0, 1.0, 0.005).with_size(96)
    model = ViewerModel(scene, view="pmd-slope", case_size=64)
    model.traced(
        render(scene, ("uv",)).uv, render(scene.without_defect(), ("uv",)).uv[..., 1].copy()
    )
    model.start_metrics()
    assert model.metrics_pending and model.readout_text()[-1] == "PMD at 64 px: computing..."
    model.wait_for_metrics()
    measured = pmd_scene(scene, 64)
    assert measured.camera.width == 64 and measured.active.emitter.measured_by == "pmd"
    with Renderer() as renderer:
        truth = measure_pmd_scene(renderer, measured, PmdSettings())
    result = model.cases.last.result
    assert model.cases.last.scene == measured and result is not None
    for name in ("pmd_shift_mm", "pmd_depth_um", "pmd_snr", "unwrap_failures", "status"):
        assert getattr(result, name) == getattr(truth, name), name
    expected = pmd_readout_lines(measured, truth, 64)
    assert model.readout_text()[:5] == expected[:5]
    assert expected[0] == f"PMD shift: {truth.pmd_shift_mm:.4g} mm on the screen"
    assert expected[2] == f"PMD depth: {truth.pmd_depth_um:.4g} um (dmax 5 um)"
    # the picture: the slope map at the image's size, its peak at the top of the scale
    rgba, scale = model.instrument_rgba()
    slope = np.hypot(*np.moveaxis(result.maps.slopes_urad, -1, 0))
    assert rgba.shape == (96, 96, 4) and scale.unit == "urad" and scale.bottom == 0.0
    assert scale.top == pytest.approx(np.nanmax(slope[~result.maps.failed]))
    lut = colour_lut(scale.cmap)
    assert (rgba[..., :3] == lut[255]).all(axis=-1).any()
    assert (rgba[..., :3] == lut[0]).all(axis=-1).sum() > 96 * 96 // 4  # the flat plate
    assert not (rgba[..., :3] == NO_VALUE_RGB).all(axis=-1).any()  # every pixel decoded
    assert "slope" in model.hover(48, 48) and "urad" in model.hover(48, 48)
    # nothing changed for the station: no job (the phase is the stripes', not the fringes')
    for change in (lambda: None, lambda: model.set("phase", 0.7)):
        change()
        model.start_metrics()
        assert model.cases.job is None
    model.view = "pmd-phase"  # another map of the same case
    model.start_metrics()
    assert model.cases.job is None
    assert model.instrument_rgba()[1].top == pytest.approx(2 * np.pi)
    model.set("dmax", 0.003)  # a new dent: one case
    model.start_metrics()
    assert model.cases.job is not None
    model.wait_for_metrics()
    # the heights are linear in the slopes: the depth scales with dmax
    assert model.cases.last.result.pmd_depth_um == pytest.approx(0.6 * truth.pmd_depth_um, rel=0.02)
    model.view = "image"
    model.start_metrics()
    assert model.cases.job is None
    assert model.readout_text() == readout_lines(model.readout)
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


@needs_display
def test_scripted_pmd_view_shows_the_map_its_colour_bar_and_the_station_numbers(tmp_path):
    """``--set view=pmd-phase``: the wrapped phase of the fringes the station decodes
    (the stripes' screen shows the fringe sequence), its colour bar with numbered
    ticks beneath the image, and the readout line of measure_pmd_scene's numbers."""
    path = tmp_path / "pmd.png"
    result = view(
        "--size", "128", "--frames", "2", "--set", "view=pmd-phase", "--screenshot", str(path)
    )  # fmt: skip
    assert result.returncode == 0, result.stderr[-3000:]
    line = next(x for x in result.stdout.splitlines() if x.startswith("readout: "))
    scene = paper_scene().with_size(128)
    with Renderer() as renderer:
        truth = measure_pmd_scene(renderer, pmd_scene(scene), PmdSettings())
    lines = pmd_readout_lines(pmd_scene(scene), truth, 128)
    assert line.startswith("readout: " + "; ".join(lines[:5])), line
    assert "PMD at 128 px: " in line and "..." not in line
    pixels = read_png(path)
    image = pixels[:128, :128].astype(int)
    assert image.std() > 30  # fringes, not a blank picture
    twilight = colour_lut("twilight").astype(int)  # every pixel a colour of the phase map
    near = np.abs(image[:, :, None, :] - twilight[None, None]).max(axis=-1).min(axis=-1)
    assert (near <= 3).mean() > 0.99
    layout = colour_bar_layout(128, 128, pixels.shape[0])
    assert not layout.overlaid
    row = int(layout.top + layout.height / 2)
    for tick in colour_bar_ticks(2 * np.pi):
        x = int(layout.left + tick.at * (layout.width - 1))
        expected = twilight[colour_index(tick.value, 2 * np.pi)]
        assert np.abs(pixels[row, x].astype(int) - expected).max() <= 12, tick
        label = pixels[
            int(layout.top + layout.height + 5) : int(layout.top + layout.height + 18),
            max(0, x - 8) : x + 8,
        ]
        assert (label.min(axis=2) > 180).sum() >= 5, tick  # its number beneath the ramp


_SWITCH = """
import sys
from pathlib import Path
import moderngl_window as mglw
from glshade.app.viewer import ViewerOptions, window
from glshade.scene import paper_scene
name, value, shot = sys.argv[1:]
options = ViewerOptions(scene=paper_scene().with_size(128), frames=8, screenshot=Path(shot))
app, _ = window.make_app(options)
class Switch(app):
    def on_render(self, time_s, frame_time):
        if self.stats["frames"] == 3:  # the panel has been drawn: a change while running
            assert self.model.set(name, value), self.model.refused
        super().on_render(time_s, frame_time)
window.loop(mglw.create_window_config_instance(Switch, args=["--window", "pyglet"]))
"""


@needs_display
@pytest.mark.parametrize(("name", "value"), [("reflection", "ggx"), ("fresnel", "conductor")])
def test_a_shading_model_changed_while_running_shows_the_batch_renderer_image(
    tmp_path, name, value
):
    """The old bug: the panel left imgui's alpha blending on, and a shading model that
    re-renders the image (rather than re-shading the uv map) came out black."""
    shot = tmp_path / "switch.png"
    command = [sys.executable, "-c", _SWITCH, name, value, str(shot)]
    if not os.environ.get("DISPLAY"):
        command = ["xvfb-run", "-a", "-s", "-screen 0 1280x1024x24", *command]
    result = subprocess.run(command, capture_output=True, text=True, timeout=180)
    assert result.returncode == 0, result.stderr[-3000:]
    shown = read_png(shot)[:128, :128, 0].astype(np.float64) / 255.0
    scene = apply_setting(paper_scene().with_size(128), name, value)
    offscreen = np.clip(render(scene).image, 0, 1)
    assert offscreen.max() > 0.05 and np.abs(shown - offscreen).mean() < 2 / 255


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
        == "glshade: error: camera.theta_deg: must be in (0.001, 90) degrees, got 120.0"
    )
    result = subprocess.run(
        [sys.executable, "-m", "glshade", "view", "--set", "theta=abc"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert (
        result.returncode == 2
        and "--set theta (camera.theta_deg): must be a number in degrees" in result.stderr
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


# --------------------------------------------------------------------------- window at rest
_RUN_WINDOW = """
import json, sys
from pathlib import Path
from glshade.app.viewer import ViewerOptions, run
from glshade.scene import paper_scene
size, view, frames, animate, shot = sys.argv[1:]
options = ViewerOptions(
    scene=paper_scene().with_size(int(size)), view=view, frames=int(frames),
    animate=animate == "1", screenshot=Path(shot),
)
stats = run(options)
stats.pop("readout")
print("stats: " + json.dumps(stats))
"""


def window_stats(tmp_path, size=512, view="image", frames=6, animate=False):
    """Run the window as ``glshade view`` does (in a subprocess, under Xvfb when there is
    no display) and return its statistics and its last frame."""
    shot = tmp_path / f"{view}_{frames}.png"
    command = [sys.executable, "-c", _RUN_WINDOW, str(size), view, str(frames)]
    command += ["1" if animate else "0", str(shot)]
    if not os.environ.get("DISPLAY"):
        command = ["xvfb-run", "-a", "-s", "-screen 0 1280x1024x24", *command]
    result = subprocess.run(command, capture_output=True, text=True, timeout=180)
    assert result.returncode == 0, result.stderr[-3000:]
    line = next(x for x in result.stdout.splitlines() if x.startswith("stats: "))
    return json.loads(line.removeprefix("stats: ")), read_png(shot)


@needs_display
def test_default_window_shows_the_whole_panel_and_a_labelled_colour_bar(tmp_path):
    """At the default size (512² image) every item of the panel is in the window, with no
    scrolling, and the displacement view has its colour bar beneath the image: the
    viewer's colour map along the ramp, and numbers under it."""
    stats, pixels = window_stats(tmp_path, view="displacement")
    width, height = stats["window_size"]
    assert stats["opened_at"] == stats["window_size"]  # it opened at a size that fits
    assert width == 512 + 360 and 512 < height <= 640  # fits a 768-pixel-high screen
    assert 0 < stats["panel_bottom"] <= height and stats["panel_scroll"] == 0
    assert pixels.shape[:2] == (height, width)
    layout = colour_bar_layout(512, 512, height)
    assert not layout.overlaid and layout.strip_bottom <= height
    top = stats["scale_top"]
    assert top == pytest.approx(18.0 / 4 * 512 / 512, rel=0.05)  # the deflection, px
    lut = colour_lut().astype(int)
    row = int(layout.top + layout.height / 2)
    ticks = colour_bar_ticks(top)
    assert len(ticks) >= 3
    for tick in ticks:
        x = int(layout.left + tick.at * (layout.width - 1))
        expected = lut[colour_index(tick.value, top)]
        assert np.abs(pixels[row, x].astype(int) - expected).max() <= 12, tick
        # the tick's number beneath the ramp: bright text on the dark strip
        label = pixels[
            int(layout.top + layout.height + 5) : int(layout.top + layout.height + 18),
            max(0, x - 12) : x + 12,
        ]
        assert (label.min(axis=2) > 180).sum() >= 5, tick
    # the image view has no bar: the strip beneath the image is the window's grey
    _, plain = window_stats(tmp_path, view="image")
    strip = plain[512:height, :512]
    assert np.abs(strip.astype(int) - plain[height - 1, 0].astype(int)).max() <= 2


@needs_display
def test_frames_for_the_panel_alone_render_no_scene(tmp_path):
    """A frame where nothing in the picture changed copies the kept picture: 30 frames
    of a still scene run the display pass at most three times; an animation runs it
    every frame."""
    still, _ = window_stats(tmp_path, size=128, frames=30)
    assert still["frames"] == 30 and still["scene_passes"] <= 3
    moving, _ = window_stats(tmp_path, size=128, frames=20, animate=True)
    assert moving["scene_passes"] >= 20 and moving["traces"] == 1


_DRIVE_IDLE = """
import ctypes, json, re, subprocess, sys, time
from pathlib import Path
out = Path(sys.argv[1])
viewer = subprocess.Popen([sys.executable, "-m", "glshade", "view", "--size", "256"], cwd=out)
x11, xtst = ctypes.CDLL("libX11.so.6"), ctypes.CDLL("libXtst.so.6")
x11.XOpenDisplay.restype = ctypes.c_void_p
display = ctypes.c_void_p(x11.XOpenDisplay(None))
def window():
    for _ in range(600):
        info = subprocess.run(["xwininfo", "-name", "glshade view"], capture_output=True,
                              text=True).stdout
        if "Map State: IsViewable" in info:
            return [int(re.search(k + r":\\s+(-?\\d+)", info).group(1))
                    for k in ("Absolute upper-left X", "Absolute upper-left Y")]
        time.sleep(0.1)
    raise SystemExit("no window")
def press(name):
    code = x11.XKeysymToKeycode(display, x11.XStringToKeysym(name.encode()))
    xtst.XTestFakeKeyEvent(display, code, 1, 0)
    xtst.XTestFakeKeyEvent(display, code, 0, 0)
    x11.XFlush(display)
def shot():
    before = set(out.glob("glshade_view_*.png"))
    press("s")
    for _ in range(600):
        new = set(out.glob("glshade_view_*.png")) - before
        if new:
            time.sleep(0.2)
            return new.pop().name
        time.sleep(0.05)
    raise SystemExit("no screenshot")
x, y = window()
xtst.XTestFakeMotionEvent(display, -1, x + 128, y + 128, 0)  # the pointer on the image
x11.XFlush(display)
time.sleep(float(sys.argv[2]))
first = shot()
time.sleep(float(sys.argv[2]))
second = shot()
press("o")
time.sleep(0.5)
third = shot()
press("p")  # the PMD phase view: the station measures, then the window rests again
time.sleep(float(sys.argv[3]))
fourth = shot()
time.sleep(float(sys.argv[2]))
fifth = shot()
press("p")  # back to the image
time.sleep(0.5)
sixth = shot()
viewer.terminate()
viewer.wait()
print("shots: " + json.dumps([first, second, third, fourth, fifth, sixth]))
"""


@needs_display
@pytest.mark.slow
@pytest.mark.skipif(
    ctypes.util.find_library("Xtst") is None or shutil.which("xwininfo") is None,
    reason="needs libXtst and xwininfo (Debian: libxtst6, x11-utils) to press keys",
)
def test_untouched_window_draws_nothing_and_still_answers_keys(tmp_path):
    """The real window, with keys pressed through XTest: the frame number in the
    screenshot's name counts the frames drawn. Seconds at rest between two presses
    draw no frame beyond the few that follow the first press; O still toggles the
    overlay, and the next screenshot shows it. P shows the PMD phase map (the station's
    result), at rest the PMD view draws nothing either, and P again shows the image as
    it was."""
    command = [sys.executable, "-c", _DRIVE_IDLE, str(tmp_path), "3", "2"]
    if not os.environ.get("DISPLAY"):
        command = ["xvfb-run", "-a", "-s", "-screen 0 1280x1024x24", *command]
    # the viewer runs in tmp_path: the glshade under test, wherever the path said it is
    source = str(Path(glshade.__file__).resolve().parents[1])
    path = os.pathsep.join([source, os.environ.get("PYTHONPATH", "")])
    env = {**os.environ, "PYTHONPATH": path}
    result = subprocess.run(command, capture_output=True, text=True, timeout=180, env=env)
    assert result.returncode == 0, result.stderr[-3000:]
    line = next(x for x in result.stdout.splitlines() if x.startswith("shots: "))
    names = json.loads(line.removeprefix("shots: "))
    frames = [int(re.search(r"_(\d+)\.png", n).group(1)) for n in names]
    assert frames[1] - frames[0] <= SETTLE_FRAMES + 1  # 3 s at rest: no frames of its own
    assert frames[2] > frames[1]
    assert frames[4] - frames[3] <= SETTLE_FRAMES + 1  # at rest in the PMD view too
    shots = [read_png(tmp_path / n)[:256, :256].astype(int) for n in names]
    overlay = shots[2]
    red = (overlay[..., 0] > 200) & (overlay[..., 2] < 80)
    blue = (overlay[..., 2] > 200) & (overlay[..., 0] < 80)
    assert red.any() and blue.any()  # the Fig. 9 contours: the key reached the viewer
    twilight = colour_lut("twilight").astype(int)  # the phase map: its colours only
    near = np.abs(shots[4][:, :, None, :] - twilight[None, None]).max(axis=-1).min(axis=-1)
    assert (near <= 3).mean() > 0.99 and shots[4].std() > 30
    assert np.array_equal(shots[5], shots[0])  # the image again, as it was


def test_the_readout_marks_numbers_it_cannot_read():
    from glshade.app.viewer.model import Readout, readout_lines

    measuring = readout_lines(Readout())
    assert measuring[-1] == "status: ..."  # the line is always there: the panel keeps its height
    lost = Readout(
        at_phase_px=0.0, visibility_px=0.0, continuous_px=0.16, deflection_px=0.16,
        status="unresolved", status_reason="the 2 mm stripes span 0.3 px per period",
    )  # fmt: skip
    lines = readout_lines(lost)
    assert lines[0].endswith("[unresolved: not measurable]")
    assert lines[1].endswith("[unresolved: not measurable]")
    assert "not measurable" not in lines[2] and "not measurable" not in lines[3]
    assert lines[-1] == "status: unresolved: the 2 mm stripes span 0.3 px per period"
    edge = readout_lines(Readout(deflection_px=3.0, status="edge", status_reason="border"))
    assert "[edge: not measurable]" in edge[3]


@needs_display
def test_a_posed_station_shows_as_the_batch_renderer_does(tmp_path):
    scene = paper_scene("sphere", 45.0, 4.0, 0.005).updated(
        camera={"pose": "look_at", "position": [60.0, 140.0, 110.0]},
        emitter={"pose": "placed", "centre": [-40.0, 300.0, -120.0]},
    )
    scene.save(tmp_path / "posed.toml")
    path = tmp_path / "posed.png"
    result = view(
        str(tmp_path / "posed.toml"), "--size", "256", "--frames", "6", "--screenshot", str(path)
    )
    assert result.returncode == 0, result.stderr[-3000:]
    shown = read_png(path)[:256, :256, 0].astype(np.float64) / 255.0
    offscreen = np.clip(render(scene.with_size(256)).image, 0, 1)
    assert shown.std() > 0.1
    assert np.abs(shown - offscreen).mean() < 2 / 255 and np.abs(shown - offscreen).max() <= 4 / 255
