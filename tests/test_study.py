"""The paper's study: a reduced run end to end, resuming, bad input."""

from __future__ import annotations

import subprocess
import sys

import pytest

from glshade.app.cli import main
from glshade.errors import GlshadeError
from glshade.measure.record import Measurement
from glshade.measure.single import measure_scene
from glshade.study import findings
from glshade.study.plan import StudyPlan
from glshade.study.run import run_study
from glshade.study.store import CSV_COLUMNS, read_results_csv

TIMING = {"trace_s", "shade_s", "contours_s", "continuous_s"}
SMALL = dict(thetas=(45.0, 5.0), size=128)


def _stable(rows):
    return [{k: v for k, v in r.items() if k not in TIMING} for r in rows]


def test_reduced_study_end_to_end_through_the_cli(tmp_path, capsys):
    out = tmp_path / "study"
    assert (
        main(["paper", "--out", str(out), "--size", "128", "--thetas", "45,5", "--no-progress"])
        == 0
    )
    assert "48 cases computed" in capsys.readouterr().out
    rows = read_results_csv(out / "results.csv")
    assert len(rows) == 3 * 2 * 4 * 2
    assert list(rows[0]) == CSV_COLUMNS
    assert {r["surface"] for r in rows} == {"flat", "cylinder", "sphere"}
    assert all(r["period_mm"] == (10.0 if r["surface"] == "sphere" else 2.0) for r in rows)
    case = {(r["surface"], r["theta_deg"], r["sigma2_mm2"], r["dmax_mm"]): r for r in rows}
    # flat, steep deep dent at 45 deg: the deflection and its continuous limit are the
    # closed form scaled to 128 px (18 / 8 px); the 2 mm stripes span 2.9 px per period at
    # this size, so the paper's contour metric has nothing resolved to measure, and says so
    flat = case[("flat", 45.0, 1.0, 0.005)]
    assert flat["deflection_px"] == pytest.approx(18.0 / 8, rel=0.05)
    assert flat["visibility_continuous_px"] == pytest.approx(flat["deflection_px"], rel=0.02)
    assert flat["deflection_law_px"] == pytest.approx(18.0 / 8, rel=0.01)
    assert flat["unresolved_fraction"] == pytest.approx(1.0) and flat["visibility_px"] == 0.0
    # ... and at 5 deg it folds, as the law predicts (at 128 px the dent spans 0.3 rows, too
    # few to resolve the cap: that is measured at 512 px and more in test_physics.py)
    grazing = case[("flat", 5.0, 1.0, 0.005)]
    assert grazing["folded"] and grazing["fold_ratio"] > 1
    # the convex sphere compresses even its 10 mm stripes below 4 px per period at this
    # size; the continuous numbers still measure the dent
    sphere = case[("sphere", 45.0, 1.0, 0.005)]
    assert sphere["unresolved_fraction"] > 0.9
    assert sphere["visibility_continuous_px"] > 0.2 and not sphere["folded"]
    assert all(0.0 <= r["unresolved_fraction"] <= 1.0 for r in rows)
    for name in (
        "fig09_contour_overlay.png",
        "fig09_contour_overlay_fold.png",
        "grid_flat_dmax5um.png",
        "grid_sphere_dmax3um.png",
        "visibility_cylinder_dmax5um.png",
        "law_vs_simulation.png",
        "report.md",
        "study.json",
    ):
        assert (out / name).stat().st_size > 0, name
    report = (out / "report.md").read_text()
    for number in range(1, 6):
        assert f"## Finding {number}" in report
    for heading in (
        "## What to do with it: where to put the camera",
        "## How the verdicts are decided",
        "## The closed forms against the simulation",
        "## Where the stripe map folds",
    ):
        assert heading in report, heading
    assert "not resolved" in report  # the flat cases at 128 px are called out
    assert not list(out.rglob("*.tmp"))


def test_resume_after_interruption_gives_the_same_results(tmp_path):
    plan = StudyPlan(surfaces=("flat", "sphere"), **SMALL)
    whole = run_study(plan, tmp_path / "whole", progress=False)

    class Stop(Exception):
        pass

    done = []

    def interrupt(row):
        done.append(row)
        if len(done) == 5:
            raise Stop

    with pytest.raises(Stop):
        run_study(plan, tmp_path / "resumed", progress=False, on_case_done=interrupt)
    assert len(list((tmp_path / "resumed" / "cases").glob("*.json"))) == 5
    assert not (tmp_path / "resumed" / "results.csv").exists()
    resumed = run_study(plan, tmp_path / "resumed", progress=False)
    assert (resumed.skipped, resumed.computed) == (5, len(plan.cases()) - 5)
    assert _stable(read_results_csv(tmp_path / "resumed" / "results.csv")) == _stable(
        read_results_csv(tmp_path / "whole" / "results.csv")
    )
    assert _stable(resumed.rows) == _stable(whole.rows)
    # a third run computes nothing
    again = run_study(plan, tmp_path / "resumed", progress=False)
    assert again.computed == 0


def test_directory_with_other_settings_is_refused(tmp_path):
    run_study(
        StudyPlan(surfaces=("flat",), thetas=(45.0,), sigma2s=(4.0,), dmaxs=(0.005,), size=64),
        tmp_path,
        progress=False,
    )
    with pytest.raises(GlshadeError, match="another plan"):
        run_study(
            StudyPlan(surfaces=("flat",), thetas=(45.0,), sigma2s=(4.0,), dmaxs=(0.005,), size=96),
            tmp_path,
            progress=False,
        )


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["--surfaces", "flat,torus"], "unknown surface 'torus'"),
        (["--surfaces", ""], "surfaces: must list at least one"),
        (["--thetas", ""], "thetas: must list at least one value"),
        (["--thetas", "5,45"], "thetas: must be strictly decreasing"),
        (["--thetas", "95,45"], "thetas: every value must be in (0, 90)"),
        (["--step", "3"], "step: must be at most one stripe period (2 mm)"),
        (["--step", "0"], "step: must be a number of mm > 0"),
        (["--sigma2s", "-1"], "sigma2s: every value must be in (0, inf)"),
        (["--workers", "0"], "--workers: must be an integer >= 1"),
        (["--size", "0"], "camera.width: must be an integer in [1, 16384]"),
    ],
)
def test_bad_input_is_one_line_exit_2(tmp_path, args, fragment):
    out = tmp_path / "out"
    result = subprocess.run(
        [sys.executable, "-m", "glshade", "paper", "--out", str(out), "--no-progress", *args],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("glshade: error: ") and fragment in lines[0], (
        result.stderr
    )
    if "--workers" not in args:
        assert not out.exists()  # rejected before anything is written


def test_output_path_that_is_a_file(tmp_path):
    target = tmp_path / "taken"
    target.write_text("keep me")
    for out, fragment in ((target, "is not a directory"), (target / "sub", "cannot create it")):
        result = subprocess.run(
            [
                sys.executable,
                "-m",
                "glshade",
                "paper",
                "--out",
                str(out),
                "--size",
                "32",
                "--no-progress",
            ],
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert result.returncode == 2 and fragment in result.stderr, result.stderr
    assert target.read_text() == "keep me"


def test_findings_rules_on_made_up_rows():
    """The verdict rules on rows built to hold or to fail each finding."""
    rows = []
    for surface in ("flat", "sphere"):
        for theta in (85.0, 45.0, 5.0):
            for sigma2 in (1.0, 4.0, 9.0, 16.0):
                for dmax in (0.003, 0.005):
                    steep = sigma2 <= 4.0
                    trend = (
                        theta / 2 if steep else (90 - theta) / 2
                    )  # finding 3 and 4 as the paper says
                    value = dmax * 1000 * (20 / sigma2) + trend
                    if surface == "sphere" and steep:
                        value = dmax * 1000 * (20 / sigma2) + 5.0  # no trend with theta
                    rows.append(
                        dict(
                            surface=surface,
                            theta_deg=theta,
                            sigma2_mm2=sigma2,
                            dmax_mm=dmax,
                            visibility_px=value,
                            visibility_continuous_px=value,
                            folded=False,
                        )
                    )
    verdicts = {
        (v.finding, v.scope): v.verdict
        for v in findings.evaluate(rows)
        if v.metric == "paper metric"
    }
    assert verdicts[(1, "flat")] == findings.HOLDS
    assert verdicts[(3, "flat, dmax 5 µm")] == findings.HOLDS
    assert verdicts[(4, "flat, dmax 5 µm")] == findings.HOLDS
    assert verdicts[(4, "sphere, dmax 5 µm")] == findings.NOT
    assert verdicts[(5, "flat, sphere")] == findings.NOT
    # a perfectly ranked but tiny trend (2 %) is only "partly"
    tiny = [
        dict(r, visibility_px=10.0 + (90 - r["theta_deg"]) / 400)
        for r in rows
        if r["surface"] == "flat"
    ]
    tiny_verdicts = {
        (v.finding, v.scope): v.verdict
        for v in findings.evaluate(tiny)
        if v.metric == "paper metric"
    }
    assert tiny_verdicts[(3, "flat, dmax 5 µm")] == findings.PARTLY
    assert findings.spearman([1, 2, 3], [3, 2, 1]) == pytest.approx(-1.0)
    assert findings.spearman([1, 2, 3], [5, 5, 5]) == 0.0


def test_a_case_is_a_pure_function_of_its_scene(tmp_path, renderer):
    """The study shares one defect-free analysis between the defects of a geometry; its
    rows are nevertheless exactly what measure_scene gives for each scene on its own."""
    plan = StudyPlan(
        surfaces=("flat", "sphere"), thetas=(45.0, 5.0), sigma2s=(1.0,), dmaxs=(0.005,), size=256
    )
    rows = run_study(plan, tmp_path, progress=False, renderer=renderer).rows
    keys = (
        "visibility_px",
        "visibility_continuous_px",
        "deflection_px",
        "folded",
        "islands",
        "best_phase_mm",
    )
    for row, case in zip(rows, plan.cases(), strict=True):
        scene = plan.scene(*case)
        alone = Measurement.of(scene, measure_scene(renderer, scene, plan.metric)).row()
        assert {k: row[k] for k in keys} == {k: alone[k] for k in keys}, case
    assert any(row["folded"] for row in rows)  # the fold case is among them


def test_findings_advice_names_the_fold_and_the_magnification():
    """The report's advice, on rows where a steep dent folds on the flat plate and every
    dent shrinks on the sphere: the θ ranges and the closed form behind each."""
    rows = []
    for theta in (85.0, 45.0, 5.0):
        for sigma2 in (1.0, 16.0):
            folded = sigma2 == 1.0 and theta == 5.0
            rows.append(
                dict(
                    surface="flat",
                    theta_deg=theta,
                    sigma2_mm2=sigma2,
                    dmax_mm=0.005,
                    folded=folded,
                    visibility_px=5.0 if folded else 18.0 / sigma2**0.5,
                    visibility_continuous_px=5.5 if folded else 18.0 / sigma2**0.5,
                    deflection_px=18.0 / sigma2**0.5,
                )
            )
            rows.append(
                dict(
                    surface="sphere",
                    theta_deg=theta,
                    sigma2_mm2=sigma2,
                    dmax_mm=0.005,
                    folded=False,
                    visibility_px=1.0,
                    visibility_continuous_px=theta / 20,
                    deflection_px=theta / 20,
                )
            )
    text = "\n".join(findings.advice(rows))
    assert "**flat, steep dents (σ² 1, 4)**: θ 85–45° (5 µm)" in text
    assert "**flat, gentle dents (σ² 9, 16)**: θ 85–5° (5 µm)" in text
    assert "moves the rays by 18.0 px and its contours by 5.5 px" in text
    assert (
        "**sphere, steep dents (σ² 1, 4)**: θ 85° (5 µm)" in text
        and "magnifies the stripes" in text
    )
    assert findings.theta_ranges({85.0, 45.0, 5.0}, (85.0, 65.0, 45.0, 5.0)) == "85°, 45–5°"
