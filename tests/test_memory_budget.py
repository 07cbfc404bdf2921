"""The memory budget covers the analysis: a sweep of many phases holds nothing per phase,
the stripe maps a baseline keeps stay within their bytes (and change no number), and a
measurement the budget cannot hold is refused before it is traced, in one line.

Memory is counted with tracemalloc (NumPy's and OpenCV's arrays are traced), never timed.
"""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from glshade.errors import GlshadeError
from glshade.gpu.renderer import Renderer
from glshade.instruments import memory
from glshade.instruments.base import Case
from glshade.instruments.pmd.baseline import pmd_baseline
from glshade.instruments.pmd.model import station_model
from glshade.instruments.pmd.station import measure_pmd_scene
from glshade.instruments.stripes.group import AHEAD
from glshade.instruments.stripes.single import measure_scene
from glshade.measure.engine import budget_plan, check_budget, measure_many
from glshade.measure.single import as_method
from glshade.metrics import visibility as vis
from glshade.scene import Scene, paper_scene
from glshade_process import run_glshade

SIZE = 128
#: How much more the analysis of 64 phases may take than that of 8 (tracemalloc peaks):
#: 1.02 times as much; before the phases were streamed it held a stripe map per phase,
#: 2.8 times as much (17 times at 512 phases).
PHASES_GROWTH = 1.5


def synthetic_maps() -> tuple[np.ndarray, np.ndarray]:
    """A flat mirror's emitter map (0.05 mm a row: 40-pixel stripes) and the same with a
    Gaussian dent's move in its middle, float32 as the renderer gives them."""
    rows, cols = np.mgrid[0:SIZE, 0:SIZE].astype(np.float64)
    v0 = 0.05 * rows
    bump = np.exp(-((rows - SIZE / 2) ** 2 + (cols - SIZE / 2) ** 2) / (2 * 12.0**2))
    return v0.astype(np.float32), (v0 + 0.3 * bump).astype(np.float32)


def pattern():
    scene = Scene()
    return scene.active.emitter.pattern(scene)


def analysis_peak(phases: int, cache_bytes: int = 0) -> tuple[int, vis.Visibility]:
    """tracemalloc's peak (bytes) of one baseline and one measurement at ``phases``
    phases per period, and the result."""
    v0, v1 = synthetic_maps()
    settings = vis.MetricSettings(step_mm=pattern().period_mm / phases)
    tracemalloc.start()
    try:
        baseline = vis.Baseline(v0, pattern(), settings, stripe_cache_bytes=cache_bytes)
        result = baseline.measure(v1)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert len(result.per_phase) == phases
    return peak, result


def test_many_phases_hold_no_state_per_phase():
    analysis_peak(8)  # the first run also traces what OpenCV and NumPy make once
    few, found_few = analysis_peak(8)
    many, found_many = analysis_peak(64)
    assert found_few.visibility_px > 0 and found_many.visibility_px > 0
    assert many < PHASES_GROWTH * few, f"8 phases: {few} bytes, 64 phases: {many} bytes"


def test_the_stripe_cache_keeps_at_most_its_bytes_and_changes_no_number():
    v0, _ = synthetic_maps()
    one_map = vis.Baseline(v0, pattern(), stripe_cache_bytes=0).normal_stripes(0.0).nbytes
    cap = 3 * one_map + one_map // 2
    _, capped = analysis_peak(64, cap)
    _, kept_none = analysis_peak(64, 0)
    _, kept_all = analysis_peak(64, vis.STRIPE_CACHE_BYTES)
    assert vis.differing_fields(capped, kept_none) == []
    assert vis.differing_fields(capped, kept_all) == []
    baseline = vis.Baseline(
        v0, pattern(), vis.MetricSettings(step_mm=pattern().period_mm / 64), stripe_cache_bytes=cap
    )
    baseline.measure(synthetic_maps()[1])
    assert 0 < len(baseline.stripe_cache) < 64
    assert baseline.stripe_cache.held_bytes <= cap


def test_the_estimate_does_not_grow_with_the_phases_and_its_advice_fits():
    scene = paper_scene().with_size(1024)
    coarse = memory.paper_estimate(scene, vis.MetricSettings(step_mm=0.25))
    fine = memory.paper_estimate(scene, vis.MetricSettings(step_mm=0.001))
    assert coarse == fine
    budget = 64 << 20
    assert coarse.required_bytes > budget
    fits = memory.largest_size(
        scene, lambda at: memory.paper_estimate(at, vis.MetricSettings()), budget
    )
    assert fits is not None
    estimate = memory.paper_estimate(scene.with_size(fits), vis.MetricSettings())
    larger = memory.paper_estimate(scene.with_size(fits + 1), vis.MetricSettings())
    assert estimate.required_bytes <= budget < larger.required_bytes
    cache = memory.stripe_cache_bytes(scene, vis.MetricSettings(), coarse, coarse.required_bytes)
    assert cache == 0  # a budget the analysis fills leaves the stripe maps nothing


def test_a_case_beyond_the_budget_is_refused_before_it_is_traced(gl_context):
    scene = paper_scene().with_size(1024)
    pmd = as_method(scene, "pmd")
    with Renderer(gl_context, memory_budget_bytes=64 << 20) as small:
        for attempt in (
            lambda: measure_scene(small, scene),
            lambda: measure_pmd_scene(small, pmd),
            lambda: list(measure_many(small, [Case(0, scene)], vis.MetricSettings())),
        ):
            with pytest.raises(GlshadeError, match="memory budget of 64 MiB") as info:
                attempt()
            assert "\n" not in str(info.value) and "1024 x 1024" in str(info.value)
        assert not small._targets  # nothing was rendered


def test_a_pmd_baseline_keeps_no_frames(renderer):
    scene = as_method(paper_scene().with_size(32), "pmd")
    baseline = pmd_baseline(renderer, station_model(scene))
    assert baseline.capture.recorded is None  # no frame kept unless asked for
    for held in (baseline.capture.white, baseline.capture.first):
        assert held.base is None  # its own array, not a layer of a read-back stack
    kept = pmd_baseline(renderer, station_model(scene), keep_frames=True)
    assert kept.capture.recorded is not None and len(kept.capture.recorded) == 32


@pytest.mark.parametrize(
    ("argv", "budget", "typed"),
    [
        (["measure", "--size", "1024", "--step", "0.001"], 64, "--step 0.001 mm: 2000 phases"),
        (["measure", "--method", "pmd", "--size", "512"], 200, "32 frames: 2 directions"),
    ],
)
def test_cli_refuses_beyond_a_small_budget_in_one_line(tmp_path, argv, budget, typed):
    env = {"GLSHADE_MEMORY_BUDGET_MB": str(budget)}
    done = run_glshade(*argv, cwd=tmp_path, env=env, timeout=300)
    err = done.stderr.strip()
    assert done.returncode == 2 and done.stdout == ""
    assert err.count("\n") == 0 and err.startswith("glshade: error: "), err
    assert "(--size): " in err and typed in err
    assert f"more than the memory budget of {budget} MiB (GLSHADE_MEMORY_BUDGET_MB)" in err
    assert "; at most --size " in err and " fits" in err
    assert list(tmp_path.iterdir()) == []


def test_a_study_is_checked_before_it_is_traced_and_queues_what_fits():
    scene = paper_scene().with_size(1024)
    settings = vis.MetricSettings()
    one = memory.paper_estimate(scene, settings, threads=1, waiting=1).required_bytes
    cases = [Case(0, scene), Case(1, paper_scene(dmax=0.003).with_size(1024))]
    check_budget(cases, settings, one)  # one thread, the caller's last result: fits
    with pytest.raises(GlshadeError, match=r"2 analysis threads \(--threads\)"):
        check_budget(cases, settings, one, threads=2, pooled=True)
    two = memory.paper_estimate(scene, settings, threads=2, waiting=1).required_bytes
    plan = budget_plan(scene, settings, two, threads=2, pooled=True)
    assert plan.ahead == 0 and plan.cache_bytes == 0  # nothing queued ahead, no maps kept
    roomy = budget_plan(scene, settings, 2 << 30, threads=2, pooled=True)
    assert roomy.ahead == AHEAD and roomy.cache_bytes > 0
