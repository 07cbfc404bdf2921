"""The paper's study under phase measuring (``glshade paper --method pmd``): its table
against the measuring floor, resuming, the report's verdicts on rows whose answers are
known by construction, and bad input. Tiny plans (64 px) keep it fast."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest

from glshade.app.cli import main
from glshade.instruments.pmd.capture import interior
from glshade.instruments.pmd.model import station_model
from glshade.instruments.pmd.station import dent_region, measure_pmd_scene
from glshade.instruments.record import PMD_COLUMN_NAMES, PmdMeasurement
from glshade.measure.single import as_method
from glshade.metrics import physics
from glshade.metrics.status import dent_window, touches_edge
from glshade.scene import paper_scene
from glshade.study import findings
from glshade.study.plan import StudyPlan
from glshade.study.pmd_findings import (
    PMD_METRICS,
    PMD_SCALES,
    best_by_depth,
    best_by_paper,
    best_by_snr,
    judged_rows,
    pair_rows,
    recoded,
    write_pmd_report,
)
from glshade.study.pmd_plan import (
    PmdChain,
    PmdStudyPlan,
    coding_periods,
    finest_period_mm,
    screen_mm_per_pixel,
)
from glshade.study.pmd_run import run_pmd_study
from glshade.study.pmd_store import PMD_STUDY_COLUMNS, read_results_csv
from glshade.study.rewrite import rewrite_pmd

SIZE = 64


def _plan(surfaces=("flat",), thetas=(45.0, 15.0)) -> PmdStudyPlan:
    cases = StudyPlan(surfaces=surfaces, thetas=thetas, sigma2s=(4.0,), dmaxs=(0.005,), size=SIZE)
    return PmdStudyPlan(cases)


# --------------------------------------------------------------------------- the chain
def test_the_chain_and_coding_are_the_stated_ones():
    plan = PmdStudyPlan(StudyPlan(surfaces=("flat", "cylinder", "sphere"), size=1024))
    flat = plan.scene("flat", 45.0, 4.0, 0.005)
    sphere = plan.scene("sphere", 45.0, 4.0, 0.005)
    assert flat.emitter.periods == (2.0, 16.0, 128.0, 1024.0)
    assert plan.coding("cylinder") == (2.0, 16.0, 128.0, 1024.0)
    assert sphere.emitter.periods == (10.0, 80.0, 640.0)  # the paper's 10 mm on its sphere
    assert flat.sensor.full_well_e == 10000.0 and flat.sensor.read_noise_e == 5.0
    assert flat.sensor.bit_depth == 12 and flat.sensor.seed == 0
    assert flat.render.supersample == 2
    assert flat.active.emitter.measured_by == "pmd"
    assert coding_periods(3.0, 300.0) == (3.0, 24.0, 192.0, 1536.0)
    own = PmdChain(periods=(4.0, 32.0, 256.0), surface_periods=(("sphere", (20.0, 400.0)),))
    assert own.coding("flat") == (4.0, 32.0, 256.0) and own.coding("sphere") == (20.0, 400.0)


def test_the_finest_period_spans_three_pixels_by_the_closed_form():
    """One pixel sees (Dc + De) p / f · m of the screen: the sphere's tangential m at a
    grazing view, the cylinder's sagittal m_s = 1 + 2 sin θ Dc De / (R (Dc + De)) from
    above."""
    lever = (175.6 + 256.0) * 0.005 / 25.0
    sphere = paper_scene("sphere", 5.0)
    m = physics.laws(sphere).magnification
    assert screen_mm_per_pixel(sphere) == pytest.approx(lever * m, rel=1e-12)
    assert finest_period_mm([sphere]) == math.ceil(3 * lever * m)  # 9.1 -> 10 mm
    cylinder = paper_scene("cylinder", 85.0)
    m_s = 1 + 2 * math.sin(math.radians(85.0)) * 175.6 * 256.0 / (70.0 * 431.6)
    assert screen_mm_per_pixel(cylinder) == pytest.approx(lever * m_s, rel=1e-12)
    assert finest_period_mm([paper_scene("flat", 5.0)]) == 2.0  # never below the paper's 2 mm
    half = PmdStudyPlan(StudyPlan(surfaces=("sphere",), size=512))
    assert half.coding("sphere")[0] == math.ceil(3 * 2 * lever * m)  # pixels twice as large
    # recoded for each θ alone: 2 mm resolves from above, so the SNR would be ×5 there
    full = {(r.surface, r.theta): r for r in recoded(PmdStudyPlan(StudyPlan(size=1024)))}
    assert (full["sphere", 85.0].finest_mm, full["sphere", 85.0].gain) == (2.0, 5.0)
    assert (full["sphere", 5.0].finest_mm, full["sphere", 5.0].gain) == (10.0, 1.0)
    assert full["flat", 5.0].gain == full["cylinder", 85.0].gain == 1.0


@pytest.mark.parametrize(
    "surface, theta, axis", [("cylinder", 85.0, 0), ("sphere", 15.0, 1), ("flat", 45.0, 1)]
)
def test_the_screen_a_pixel_sees_agrees_with_the_traced_map(renderer, surface, theta, axis):
    """The closed form against the renderer's exact screen map at the gaze point: the
    cylinder's columns (sagittal), the sphere's rows (tangential), the flat plate's."""
    scene = paper_scene(surface, theta, 4.0, 0.0).with_size(SIZE)
    uv = renderer.render(scene, ("uv",)).output("uv").astype(np.float64)
    c = SIZE // 2
    if axis == 0:  # u along the columns
        traced = abs(uv[c, c + 1, 0] - uv[c, c - 2, 0]) / 3.0
    else:  # v along the rows
        traced = abs(uv[c + 1, c, 1] - uv[c - 2, c, 1]) / 3.0
    assert traced == pytest.approx(screen_mm_per_pixel(scene), rel=0.03)


def test_a_pixel_straddling_the_screens_edge_is_not_the_dents_region():
    """With several rays per pixel, a pixel on the edge of what sees the screen jumps by a
    share of its footprint when the dent's faint tail moves the edge across it: that is
    not the dent, and its case is not at an edge. A dent whose own moves reach the edge
    still is."""
    scene = as_method(paper_scene("flat", 45.0, 4.0, 0.005), "pmd").with_size(SIZE)
    window = dent_window(scene, (SIZE, SIZE))
    rows, cols = np.nonzero(window)
    edge = int(cols.min()) + 2  # the first column that sees the screen, inside the window
    r, c = np.mgrid[0:SIZE, 0:SIZE].astype(float)
    exact0 = np.stack([0.3 * c, 0.3 * r], axis=-1)
    exact0[:, :edge] = np.nan

    def moved(centre_col: float, width: float) -> np.ndarray:
        bump = np.exp(-((r - SIZE / 2) ** 2 + (c - centre_col) ** 2) / (2 * width**2))
        return exact0 + bump[..., None] * np.array([1.0, 0.0])

    exact1 = moved(SIZE / 2, 2.0)
    exact1[SIZE // 2, edge] += 0.5  # the straddling pixel's jump: half the dent's peak
    region = dent_region(station_model(scene), exact0, exact1)
    seen = interior(np.all(np.isfinite(exact0), axis=-1))
    assert region[SIZE // 2, SIZE // 2] and not region[SIZE // 2, edge]
    assert touches_edge(region, seen) is None
    reaching = dent_region(station_model(scene), exact0, moved(edge + 3, 4.0))
    assert touches_edge(reaching, seen) == "the edge of the region that sees the emitter"


def test_a_sensor_with_supersampling_renders(renderer):
    """The exposure of a supersampled scene with a sensor is traced with its samples
    counted (it failed with a KeyError before)."""
    scene = (
        paper_scene()
        .with_size(32)
        .updated(sensor={"full_well_e": 10000.0}, render={"supersample": 2})
    )
    image = renderer.render(scene, ("image",)).output("image")
    assert image.shape == (32, 32) and 0.0 < float(np.nanmax(image)) <= 1.0


# --------------------------------------------------------------------------- the table
def test_rows_equal_the_measuring_floor_and_resume_skips_finished_cases(tmp_path, renderer):
    plan = _plan()
    out = tmp_path / "study"
    first = run_pmd_study(plan, out, renderer=renderer, progress=False)
    assert (first.computed, first.skipped) == (2, 0)
    with open(out / "pmd_results.csv", newline="") as fh:
        header = next(csv.reader(fh))
    assert header == [c.name for c in PMD_STUDY_COLUMNS]
    assert header[5:] == list(PMD_COLUMN_NAMES)
    rows = read_results_csv(out / "pmd_results.csv")
    assert [r.case for r in rows] == plan.cases()
    for row in rows:
        scene = plan.scene(*row.case)
        alone = PmdMeasurement.of(scene, measure_pmd_scene(renderer, scene, plan.settings))
        assert {k: row[k] for k in alone.outputs()} == alone.outputs()
        assert row.period_mm == plan.coding("flat")[0] == 5.0  # 3 pixels of 1.38 mm at 64²
    # a finished case is never measured again; a missing one is
    (out / "pmd_cases" / "flat_theta15_sigma2_4_dmax5um.json").unlink()
    said: list[str] = []
    again = run_pmd_study(plan, out, renderer=renderer, progress=False, notify=said.append)
    assert (again.computed, again.skipped, said) == (1, 1, [])
    assert read_results_csv(out / "pmd_results.csv")[1].outputs() == rows[1].outputs()
    # an edited case file fails its checksum: measured again, and said
    marked = out / "pmd_cases" / "flat_theta45_sigma2_4_dmax5um.json"
    data = json.loads(marked.read_text())
    data["pmd_snr"] = 12345.0
    marked.write_text(json.dumps(data))
    third = run_pmd_study(plan, out, renderer=renderer, progress=False, notify=said.append)
    assert (third.computed, third.skipped) == (1, 1)
    assert third.rows[0].outputs() == rows[0].outputs()
    assert said == [
        "1 case file could not be trusted and is measured again: "
        "flat_theta45_sigma2_4_dmax5um.json fails its checksum (edited or damaged)"
    ]


def test_a_directory_holding_another_pmd_plan_is_refused(tmp_path, renderer):
    out = tmp_path / "study"
    run_pmd_study(_plan(thetas=(45.0,)), out, renderer=renderer, progress=False)
    other = PmdStudyPlan(_plan(thetas=(45.0,)).cases_plan, PmdChain(seed=1))
    with pytest.raises(Exception, match="another plan"):
        run_pmd_study(other, out, renderer=renderer, progress=False)
    assert not (out / "results.csv").exists()  # the stripe study's files are not touched


# --------------------------------------------------------------------------- verdicts
THETAS = (85.0, 45.0, 5.0)


def _made_rows():
    """Flat plate, σ² 1 and 16, 3 and 5 µm, θ 85/45/5. The paper metric: the steep dent
    fades as θ falls (a fold), the gentle one grows; PMD: SNR constant over θ for the
    gentle dent, a steep dent best at θ 45; one PMD case (θ 5, σ² 1, 5 µm) is unreadable
    with an absurd SNR."""
    pmd, paper = [], []
    for s2 in (1.0, 16.0):
        for d in (0.003, 0.005):
            for t in THETAS:
                steep = s2 == 1.0
                snr = (300.0 if t == 45.0 else 280.0) if steep else 100.0
                snr *= d / 0.003
                depth = 1000 * d * (1.0 + {85.0: 0.08, 45.0: 0.01, 5.0: 0.03}[t])
                status = "edge" if (t, s2, d) == (5.0, 1.0, 0.005) else "ok"
                shift = 0.8 * d / 0.003 / math.sqrt(s2)
                pmd.append({
                    "surface": "flat", "theta_deg": t, "sigma2_mm2": s2, "dmax_mm": d,
                    "period_mm": 2.0, "pmd_shift_mm": shift, "pmd_shift_law_mm": shift / 1.01,
                    "pmd_noise_mm": 0.0034, "pmd_noise_predicted_mm": 0.0034,
                    "pmd_noise_floor_mm": 0.02,
                    "pmd_snr": 1e9 if status != "ok" else snr, "pmd_depth_um": depth,
                    "unwrap_failures": 0, "status": status,
                    "status_reason": "made up" if status != "ok" else "",
                })  # fmt: skip
                vis = (
                    {85.0: 10.0, 45.0: 8.0, 5.0: 3.0}[t]
                    if steep
                    else {85.0: 3.0, 45.0: 4.0, 5.0: 5.0}[t]
                )
                vis *= d / 0.003
                fold = 2.0 if steep else 0.2
                paper.append({
                    "surface": "flat", "theta_deg": t, "sigma2_mm2": s2, "dmax_mm": d,
                    "visibility_px": vis, "visibility_continuous_px": vis,
                    "deflection_px": 10.0 * d / 0.003 if steep else vis, "fold_ratio": fold,
                    "folded": fold > 1, "status": "ok", "status_reason": "",
                })  # fmt: skip
    return pmd, paper


def _verdicts(rows, metrics, scales=None):
    return {
        (v.finding, v.scope, v.metric): v.verdict for v in findings.evaluate(rows, metrics, scales)
    }


def test_findings_for_both_instruments_on_made_rows():
    pmd, paper = _made_rows()
    pairs = pair_rows(pmd, paper)
    ours = _verdicts(judged_rows(pairs), PMD_METRICS, PMD_SCALES)
    theirs = _verdicts(paper, {"visibility_px": "paper metric"})
    assert theirs[(3, "flat, dmax 3 µm", "paper metric")] == findings.HOLDS
    assert theirs[(4, "flat, dmax 3 µm", "paper metric")] == findings.HOLDS
    assert ours[(3, "flat, dmax 3 µm", "PMD SNR")] == findings.NOT  # constant over θ
    assert ours[(1, "flat", "PMD SNR")] == findings.HOLDS
    assert ours[(2, "flat, dmax 5 µm", "PMD shift")] == findings.HOLDS


def test_best_theta_leaves_unreadable_cases_out():
    pmd, paper = _made_rows()
    steep5 = [r for r in pmd if r["sigma2_mm2"] == 1.0 and r["dmax_mm"] == 0.005]
    snr = best_by_snr(steep5)
    assert snr.theta == 45.0 and snr.excluded == 1  # not θ 5, whose SNR is unreadable
    assert snr.near == [85.0, 45.0]  # 280 ≥ 0.9 × 300 (θ 5 is unreadable)
    depth = best_by_depth(steep5)
    assert depth.theta == 45.0 and depth.near == [45.0]
    gentle = [r for r in paper if r["sigma2_mm2"] == 16.0 and r["dmax_mm"] == 0.003]
    assert best_by_paper(gentle).theta == 5.0


def test_report_numbers_carry_their_status(tmp_path):
    pmd, paper = _made_rows()
    plan = PmdStudyPlan(
        StudyPlan(
            surfaces=("flat",), thetas=THETAS, sigma2s=(1.0, 16.0), dmaxs=(0.003, 0.005), size=SIZE
        )
    )
    path = write_pmd_report(pmd, paper, tmp_path, plan, [], 1024)
    text = path.read_text()
    assert "1 of 12 cases not measurable" in text
    assert "1e+09" not in text and "1000000000" not in text  # the unreadable SNR is never shown
    assert "*edge*" in text
    # the folded cases: the paper's limit keeps 30 % to 100 %, PMD's shift is 1 % above its law
    assert "shift / law − 1 is +1.0% (median +1.0%) on these cases" in text
    assert (
        "| flat | 1 | 3 µm | 45° (300) | 85–5° | 45° (1.0%) | 45–5° | 85° (10 px) | 0 / 0 |" in text
    )


# --------------------------------------------------------------------------- the CLI
@pytest.mark.slow
def test_end_to_end_runs_the_stripe_study_first(tmp_path, capsys):
    out = tmp_path / "study"
    args = ["paper", "--method", "pmd", "--out", str(out), "--size", str(SIZE),
            "--surfaces", "flat", "--thetas", "45,15", "--sigma2s", "4", "--dmaxs", "5um",
            "--no-progress"]  # fmt: skip
    assert main(args) == 0
    for name in ("results.csv", "report.md", "pmd_results.csv", "pmd_report.md",
                 "pmd_study.json", "pmd_depth.png", "pmd_visibility_flat_dmax5um.png"):  # fmt: skip
        assert (out / name).is_file(), name
    stripes = (out / "results.csv").read_bytes()
    assert main(args) == 0  # resumed: nothing measured again, the stripe study untouched
    assert (out / "results.csv").read_bytes() == stripes
    assert "0 PMD cases computed, 2 resumed" in capsys.readouterr().out
    text = (out / "pmd_report.md").read_text()
    rewrite_pmd(out)  # the report again from the stored tables, without measuring
    again = (out / "pmd_report.md").read_text()
    assert "## Run time" in text and "## Run time" not in again
    assert text.startswith(again.rstrip("\n"))


@pytest.mark.parametrize(
    "extra, fragment",
    [
        (["--method", "nonsense"], "invalid choice: 'nonsense'"),
        (["--supersample", "3"], "--supersample: belongs to phase measuring (--method pmd)"),
        (["--method", "pmd", "--step", "0.5"], "--step: belongs to the paper's stripe metric"),
        (["--method", "pmd", "--periods", "cone=2,16,128,1024"], "not a surface of this study"),
        (["--method", "pmd", "--periods", "2,16,128"], "300"),
        (["--method", "pmd", "--bit-depth", "9"], "sensor.bit_depth"),
    ],
)
def test_bad_input_is_one_line_exit_2_and_writes_nothing(tmp_path, capsys, extra, fragment):
    out = tmp_path / "nothing"
    assert main(["paper", "--out", str(out), "--size", str(SIZE), *extra]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("glshade: error:") and fragment in err
    assert not out.exists()


def test_pmd_results_columns_are_documented():
    """docs/results.md holds the table generated from the PMD study's column schema."""
    from pathlib import Path

    from glshade.instruments.record import columns_markdown

    doc = (Path(__file__).parents[1] / "docs" / "results.md").read_text()
    assert columns_markdown(PMD_STUDY_COLUMNS) in doc


def test_the_flags_state_the_chains_defaults():
    from glshade.app.commands.paper_pmd import CHAIN_FIELDS, CHAIN_FLAGS

    chain = PmdChain()
    for flag, (_, default, _) in CHAIN_FLAGS.items():
        assert getattr(chain, CHAIN_FIELDS[flag]) == default, flag


@pytest.mark.slow
def test_the_study_on_two_dask_workers_writes_the_same_table(tmp_path, renderer):
    """One execution path: the PMD study measured by Dask worker processes, as sweeps and
    the stripe study are, gives the in-process table (every column but the timings)."""
    from glshade.measure.executors import Distribution

    plan = _plan()
    here, there = tmp_path / "here", tmp_path / "there"
    run_pmd_study(plan, here, renderer=renderer, progress=False)
    result = run_pmd_study(plan, there, distribution=Distribution(workers=2), progress=False)
    assert result.computed == 2
    near, far = (read_results_csv(out / "pmd_results.csv") for out in (here, there))
    assert [row.outputs() for row in far] == [row.outputs() for row in near]
    assert [row.case for row in far] == plan.cases()
