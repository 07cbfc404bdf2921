"""Choosing the fringe coding (``glshade coding``): the rendered modulation against the
box-footprint closed form on a flat mirror and its further fall behind a defocused lens;
the recommended shifts measured end to end against the target noise; the ladder's
unwrapping margin against the noise law computed by hand; the memory budget (the
budget a coding needs, named exactly, and the least noise within a smaller one); the
finest period's floor; the closed forms themselves; the JSON keys, the text, the outputs
and the one-line refusals."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from glshade.app.cli import main
from glshade.components.emitter.fringes.table import FringesTable, fringes_of
from glshade.errors import GlshadeError
from glshade.instruments.memory import check_pmd, pmd_estimate
from glshade.instruments.pmd import coding, coding_files
from glshade.instruments.pmd.coding import CodingSettings, choose_coding
from glshade.instruments.pmd.station import measure_pmd_scene
from glshade.measure.single import as_method
from glshade.metrics import coding_laws as laws
from glshade.scene import Scene, paper_scene

SENSOR = {"full_well_e": 10000.0, "read_noise_e": 5.0, "bit_depth": 12}
FAST = CodingSettings(candidates=16)


def flat(size: int = 64, supersample: int = 4, **camera) -> Scene:
    """The paper's flat plate at θ 45° (its stripes: the command shows fringes there)."""
    scene = paper_scene("flat", theta_deg=45.0).with_size(size)
    return scene.updated(render={"supersample": supersample}, camera=camera)


def screen(**values) -> FringesTable:
    return fringes_of(paper_scene().updated(emitter={"kind": "fringes", **values}))


@pytest.fixture(scope="module")
def pinhole(_session_renderer):
    return choose_coding(_session_renderer, flat(), FAST)


# --------------------------------------------------------------------------- closed forms
def test_box_share_is_the_sampled_sinc():
    periods = np.array([0.5, 1.0, 2.0, 4.0])
    assert np.allclose(laws.box_share(1.0, periods, samples=1), 1.0)  # point samples
    x = math.pi / periods
    assert np.allclose(laws.box_share(1.0, periods), np.abs(np.sin(x) / x))
    assert np.allclose(laws.box_share(1.0, periods, samples=2), np.abs(np.cos(x / 2)))
    assert np.allclose(laws.box_share(1.0, periods, samples=4096), laws.box_share(1.0, periods))
    assert laws.box_share(1.0, np.array([1.0]), samples=4)[0] == pytest.approx(0.0, abs=1e-12)


def test_disc_share_is_the_jinc():
    from scipy.special import j1

    assert np.allclose(laws.disc_share(0.0, np.array([1.0, 3.0])), 1.0)
    x = math.pi * 2.0 / 5.0
    assert laws.disc_share(2.0, np.array([5.0]))[0] == pytest.approx(2 * j1(x) / x)
    # the first zero of J1 at 3.8317: a disc of 1.2197 periods averages the fringe out
    assert laws.disc_share(3.8317 / math.pi, np.array([1.0]))[0] == pytest.approx(0, abs=1e-4)


def test_the_footprint_and_blur_closed_forms():
    scene = flat(size=1024)
    dc, de = 175.6, 256.0
    assert laws.footprint_mm(scene, "v") == pytest.approx((dc + de) * 0.005 / 25.0)
    assert laws.footprint_mm(scene, "u") == pytest.approx((dc + de) * 0.005 / 25.0)
    assert laws.blur_mm(scene, "v") == 0.0
    lens = scene.updated(camera={"f_number": 8.0})  # focused on the surface, Dc
    assert laws.blur_mm(lens, "v") == pytest.approx(25.0 / 8.0 * de / dc)
    sharp = scene.updated(camera={"f_number": 8.0, "focus_distance": dc + de})
    assert laws.blur_mm(sharp, "u") == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize(("surface", "theta"), [("cylinder", 45.0), ("sphere", 25.0)])
def test_the_footprint_is_the_traced_maps_step_at_the_gaze_point(renderer, surface, theta):
    # the paper's cylinder (axis z) magnifies u only (sagittal), the sphere both, unequally
    scene = paper_scene(surface, theta_deg=theta).with_size(64).without_defect()
    uv = renderer.render(scene, ("uv",)).output("uv").astype(np.float64)
    step_v = abs(uv[32, 31, 1] - uv[31, 31, 1])  # one row down, across the gaze point
    step_u = abs(uv[31, 32, 0] - uv[31, 31, 0])  # one column right
    # a finite step of a curved map: its closed form at the gaze point within 2 %
    assert laws.footprint_mm(scene, "v") == pytest.approx(step_v, rel=0.02)
    assert laws.footprint_mm(scene, "u") == pytest.approx(step_u, rel=0.02)


def test_the_screen_gamma_aliasing_of_docs_pmd():
    em = screen(gamma=2.2, levels=0)  # continuous: no rounding
    harmonics = laws.screen_harmonics(em)
    assert laws.gamma_error_rad(harmonics, 3) == pytest.approx(0.28, rel=0.05)
    assert laws.gamma_error_rad(harmonics, 4) == pytest.approx(0.011, rel=0.05)
    assert laws.gamma_error_rad(harmonics, 8) == pytest.approx(4e-5, rel=0.1)
    linear = laws.screen_harmonics(screen(levels=0))
    assert linear[1] == pytest.approx(0.5) and laws.gamma_error_rad(linear, 3) < 1e-12


def test_rounding_and_ladders():
    assert laws.round_up(0.1837) == 0.19 and laws.round_up(330.0) == 330.0
    assert laws.round_up(301.0) == 310.0 and laws.round_near(22.57) == 23.0
    assert laws.ladder(0.2, 330.0, 2) == (0.2, 330.0)
    four = laws.ladder(0.18, 330.0, 4)
    assert four[0] == 0.18 and four[-1] == 330.0 and len(four) == 4
    ratios = np.diff(np.log(four))
    assert np.allclose(ratios, ratios.mean(), atol=0.05)


def test_finest_resolved_interpolates_from_the_coarse_side():
    periods = np.array([1.0, 2.0, 4.0, 8.0])
    found = laws.finest_resolved(periods, np.array([0.9, 0.2, 0.4, 0.8]), 0.5)
    # 0.4 at 4 mm, 0.8 at 8 mm: the level 0.5 a quarter of the way in log period
    assert found.period_mm == pytest.approx(4.0 * 2.0**0.25)
    assert found.status == "ok"  # the side lobe at 1 mm does not count
    assert laws.finest_resolved(periods, np.full(4, 0.9), 0.5).status == "below_range"
    none = laws.finest_resolved(periods, np.full(4, 0.3), 0.5)
    assert none.status == "unresolved" and math.isnan(none.period_mm)


def test_the_margin_of_an_error_budget():
    budget = laws.ErrorBudget((1.0, 10.0), (0.01, 0.02), (0.0, 0.0))
    assert budget.margins() == pytest.approx((math.pi / (10 * 0.02 + 0.01),))
    tight = laws.ErrorBudget((1.0, 10.0), (0.01, 0.02), (0.1, 0.31))
    assert tight.margins()[0] == 0.0  # 10 · 0.31 + 0.1 > π: no room left


def test_settings_refuse_in_one_line():
    for bad in ({"target_noise_mm": 0.0}, {"target_noise_mm": -1e-3},
                {"resolved_share": 1.0}, {"margin_sigmas": 0.5}, {"candidates": 4}):  # fmt: skip
        with pytest.raises(GlshadeError) as info:
            CodingSettings(**bad)
        assert "\n" not in str(info.value) and next(iter(bad)) in str(info.value)


# --------------------------------------------------------------------------- rendered
def test_the_rendered_modulation_follows_the_box_footprint(pinhole):
    probe = pinhole.probe
    assert probe.in_window and probe.pixels > 100
    w = laws.footprint_mm(flat(), "v")
    expected = laws.box_share(w, probe.periods_mm, samples=4)
    for i in range(2):
        assert np.abs(probe.share[i] - expected).max() < 0.01
    assert np.allclose(pinhole.closed_form, expected)
    # the level 0.5 of |sin x / (4 sin(x/4))| lies at x = 1.8676 (solved): p = π w / x
    assert pinhole.resolved.period_mm == pytest.approx(math.pi * w / 1.8676, rel=0.02)


def test_a_defocused_lens_lowers_the_modulation_further(_session_renderer, pinhole):
    lens = flat(f_number=16.0, aperture_samples=16)
    report = choose_coding(_session_renderer, lens, FAST)
    pin, blurred = pinhole.probe.share, report.probe.share
    falling = (pinhole.closed_form[0] > 0.3) & (pinhole.closed_form[0] < 0.95)
    assert falling.sum() >= 3
    assert np.all(blurred[:, falling] < pin[:, falling] - 0.05)
    assert report.resolved.period_mm > 1.4 * pinhole.resolved.period_mm
    # the lens's closed form (box times disc) within what 16 aperture samples resolve
    assert np.abs(blurred - report.closed_form).max() < 0.05
    assert report.blur_mm["v"] == pytest.approx(25.0 / 16.0 * 256.0 / 175.6)


def test_a_glossy_finish_picks_longer_periods_by_its_closed_form(_session_renderer, pinhole):
    """The finish is in the rendered modulation and in its closed form (box times the
    lobe's transfer), so the finest period the coding recommends grows with the lobe."""
    gloss = flat().updated(render={"reflection": "beckmann", "roughness": 1.5e-3})
    report = choose_coding(_session_renderer, gloss, FAST)
    assert np.abs(report.probe.share - report.closed_form).max() < 0.02
    assert report.resolved.period_mm > 1.4 * pinhole.resolved.period_mm
    assert report.recommended.periods_mm[0] >= report.resolved.period_mm * 0.999
    assert any("the finish (beckmann, roughness 0.0015)" in note for note in report.notes)


def test_no_fringe_under_two_screen_pixels(_session_renderer, pinhole):
    """A screen of 1.5 mm pixels shows no fringe under 3 mm, whatever the camera resolves."""
    coarse = flat().updated(emitter={"kind": "fringes", "pixel_pitch": 1.5})
    assert pinhole.recommended.periods_mm[0] < 3.0
    report = choose_coding(_session_renderer, coarse, FAST)
    assert report.recommended.periods_mm[0] >= 3.0
    assert any("at least 2 of the screen's 1.5 mm pixels" in note for note in report.notes)


def test_the_recommended_shifts_reach_the_target_when_measured(_session_renderer):
    target = 2e-3
    scene = flat(size=128).updated(sensor=SENSOR)
    report = choose_coding(_session_renderer, scene, CodingSettings(target_noise_mm=target))
    rec = report.recommended
    assert rec.status == "ok" and rec.noise_mm <= target
    assert rec.shifts > 4  # the target asks for more than the default
    fewer = coding.coordinate_noise_mm(report.probe, rec.periods_mm[0], rec.shifts - 1)
    assert fewer > target  # the smallest N
    measured = measure_pmd_scene(_session_renderer, coding_files.coded_scene(report))
    assert measured.status == "ok" and measured.unwrap_failures == 0
    assert 0.8 * target < measured.pmd_noise_mm < 1.15 * target
    assert measured.pmd_noise_mm == pytest.approx(rec.noise_mm, rel=0.1)


def test_the_ladder_keeps_the_unwrapping_margin(_session_renderer):
    scene = flat(size=64).updated(sensor={**SENSOR, "full_well_e": 2000.0})
    settings = CodingSettings(target_noise_mm=0.01, candidates=16)
    report = choose_coding(_session_renderer, scene, settings)
    rec = report.recommended
    assert rec.periods_mm[-1] >= 1.1 * 300.0 and rec.status == "ok"
    # the noise law by hand: auto exposure puts the brightest fringe (offset + amplitude,
    # 1 on this mirror) at 0.9, so the mean level A = 0.45 and the modulation 0.45 × share
    level, full_well = 0.45, 2000.0
    sigma_i = math.sqrt(level / full_well + (5.0 / full_well) ** 2 + (1 / 4095) ** 2 / 12)
    w = laws.footprint_mm(scene, "v")
    for fine, coarse in zip(rec.periods_mm, rec.periods_mm[1:], strict=False):
        ratio = coarse / fine
        noise = [
            math.sqrt(2 / rec.shifts) * sigma_i / (level * laws.box_share(w, [p], 4)[0])
            for p in (fine, coarse)
        ]
        assert settings.margin_sigmas * (ratio * noise[1] + noise[0]) < 0.95 * math.pi
    # one period fewer breaks it: the ladder is the shortest
    shorter = laws.ladder(rec.periods_mm[0], rec.periods_mm[-1], len(rec.periods_mm) - 1)
    judged = coding.judge_plan(report.scene, report.probe, shorter, rec.shifts, settings)
    assert judged.margin_sigmas < settings.margin_sigmas and judged.status == "unsafe"


@pytest.fixture(scope="module")
def two_microns(_session_renderer):
    """The flat plate at 128² through a sensor, coded for a noise of 2 µm (N 14, three
    periods: 84 frames), under the default memory budget."""
    scene = flat(size=128).updated(sensor=SENSOR)
    settings = CodingSettings(target_noise_mm=2e-3)
    return choose_coding(_session_renderer, scene, settings), settings


def test_a_coding_beyond_the_memory_budget_names_the_budget_it_needs(two_microns):
    """Under a budget 4 MiB short of what measuring the recommended coding takes, the
    report keeps the coding that reaches the target and says ``over_budget``, naming the
    GLSHADE_MEMORY_BUDGET_MB it needs: exactly, the coded scene passes the check
    ``glshade measure --method pmd`` makes under it and fails 1 MiB below. It also names
    the least noise within the smaller budget: fewer shifts, above the target, a coding
    that passes the check there."""
    roomy, settings = two_microns
    rec = roomy.recommended
    assert rec.status == "ok" and roomy.within_budget is None
    assert rec.frames == 2 * len(rec.periods_mm) * rec.shifts
    assert rec.memory_bytes == pmd_estimate(coding_files.coded_scene(roomy)).required_bytes
    small = rec.memory_bytes - (4 << 20)
    report = coding.judge(roomy.scene, roomy.probe, settings, small)
    tight = report.recommended
    assert tight.status == "over_budget"
    assert (tight.periods_mm, tight.shifts) == (rec.periods_mm, rec.shifts)
    assert f"GLSHADE_MEMORY_BUDGET_MB={tight.budget_mib}" in tight.reason
    assert "\n" not in tight.reason
    coded = coding_files.coded_scene(report)
    check_pmd(coded, tight.budget_mib << 20)
    with pytest.raises(GlshadeError, match="memory budget"):
        check_pmd(coded, (tight.budget_mib - 1) << 20)
    fallback = report.within_budget
    assert fallback is not None and fallback.status == "ok"
    assert fallback.shifts < rec.shifts and fallback.noise_mm > settings.target_noise_mm
    assert f"N {fallback.shifts}," in tight.reason
    check_pmd(coding.coded(report.scene, fallback.periods_mm, fallback.shifts), small)
    # one shift more would not fit: it is the most the budget holds
    more = coding.judge_plan(report.scene, report.probe, fallback.periods_mm,
                             fallback.shifts + 1, settings, small)  # fmt: skip
    assert more.status == "over_budget"


def test_the_dent_shift_carries_its_laws_caveat(two_microns):
    """The ranges give the dent's closed-form shift with whether it holds: ``ok`` on the
    flat plate, ``grazing`` for a wide dent seen at θ 5° on the sphere (docs/physics.md)."""
    report, _ = two_microns
    assert report.ranges.shift_status == "ok" and report.ranges.shift_reason == ""
    sphere = as_method(paper_scene("sphere", 5.0, 16.0), "pmd")
    grazing = coding.ranges(sphere, report.probe, report.recommended)
    assert grazing.shift_status == "grazing"
    assert "local elevation" in grazing.shift_reason


def test_the_finest_period_keeps_its_floor(two_microns, pinhole):
    """The one place a lower bound on the finest period applies: today none (0), and a
    floor above the least-noise period moves the recommendation up to it."""
    report, settings = two_microns
    assert coding.finest_floor_mm(report.scene) == 0.0
    best = coding.best_finest(report.probe, report.resolved, settings.resolved_share)
    assert best == report.recommended.periods_mm[0]
    floored = coding.best_finest(report.probe, report.resolved, 0.5, floor_mm=3.0 * best)
    assert floored >= 3.0 * best
    no_noise = coding.best_finest(pinhole.probe, pinhole.resolved, 0.5, floor_mm=7.0)
    assert no_noise == 7.0


def test_without_a_sensor_the_shifts_stay_and_the_noise_is_zero(pinhole):
    rec = pinhole.recommended
    assert not pinhole.sensor and rec.noise_mm == 0.0 and rec.shifts == 4
    assert any("no sensor" in note for note in pinhole.notes)
    assert rec.quantisation_mm > 0.0  # the screen's 256 levels: a fixed pattern


def test_a_dent_outside_the_image_leaves_its_ranges_unreadable(_session_renderer):
    scene = flat(size=64).updated(defect={"x0": 200.0})
    report = choose_coding(_session_renderer, scene, FAST)
    assert not report.probe.in_window
    assert report.ranges.status == "outside"
    assert all(math.isnan(v) for v in report.ranges.slope_range_mrad.values())
    assert math.isfinite(report.resolved.period_mm)  # taken over every seen pixel


# --------------------------------------------------------------------------- command line
def test_json_keys(capsys):
    args = ["coding", "--size", "64", "--supersample", "4", "--set", "sensor.full_well_e=10000"]
    assert main([*args, "--target-noise", "5um", "--candidates", "12", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert {"modulation", "finest_resolved_mm", "recommended", "current", "ranges",
            "slope_noise_urad", "notes", "sensor", "target_noise_mm"} <= set(out)  # fmt: skip
    assert out["target_noise_mm"] == pytest.approx(0.005)
    assert {"periods_mm", "v", "u", "pixels"} <= set(out["modulation"])
    assert {"rendered", "closed_form", "pixel_box", "footprint_mm", "blur_mm",
            "finest_resolved_mm"} <= set(out["modulation"]["v"])  # fmt: skip
    assert len(out["modulation"]["v"]["rendered"]) == 12
    rec = out["recommended"]
    assert {"periods_mm", "shifts", "ratios", "noise_mm", "margin_sigmas", "status",
            "frames", "memory_mib"} <= set(rec)  # fmt: skip
    assert rec["noise_mm"] <= 0.005 and rec["periods_mm"][-1] >= 330
    assert rec["memory_mib"] <= out["memory_budget_mib"] and out["within_budget"] is None
    assert {"unambiguous_mm", "slope_range_mrad", "dent_shift_mm", "snr_recommended",
            "status", "dent_shift_status", "dent_shift_reason"} <= set(out["ranges"])  # fmt: skip
    assert out["ranges"]["dent_shift_status"] == "ok"


def test_text_plot_and_coded_scene(tmp_path, capsys):
    plot, coded = tmp_path / "m.png", tmp_path / "coded.toml"
    args = ["coding", "--size", "64", "--supersample", "4", "--candidates", "12"]
    assert main([*args, "--plot", str(plot), "--coded-scene", str(coded)]) == 0
    text = capsys.readouterr().out
    for words in ("finest resolved period", "mm", "shifts N", "unambiguous range",
                  "slope range", "mrad", "no sensor", "expected SNR",
                  "within the memory budget of", "GLSHADE_MEMORY_BUDGET_MB >="):  # fmt: skip
        assert words in text, words
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    scene = Scene.load(coded)
    assert scene.emitter.kind == "fringes" and scene.emitter.periods[-1] >= 330.0


@pytest.mark.parametrize(
    ("extra", "words"),
    [
        (["--target-noise", "0"], ["--target-noise", "> 0"]),
        (["--target-noise", "-2um"], ["--target-noise"]),
        (["--resolved-share", "1.5"], ["--resolved-share", "(0, 1)"]),
        (["--margin", "0"], ["--margin"]),
        (["--candidates", "3"], ["--candidates"]),
        (["--plot", "out.jpg"], ["--plot", "lossy"]),
        (["--plot", "/nonexistent/dir/m.png"], ["--plot", "does not exist"]),
        (["--coded-scene", "coded.png"], ["--coded-scene", ".toml"]),
        (["--set", "emitter.kind=fringes", "--set", "emitter.amplitude=0"], ["amplitude"]),
    ],
)
def test_bad_input_is_one_line_and_exit_2(extra, words, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["coding", "--size", "64", *extra]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert captured.out == "" and err.count("\n") == 0 and "Traceback" not in err
    for word in words:
        assert word in err, err
    assert list(tmp_path.iterdir()) == []  # nothing written
