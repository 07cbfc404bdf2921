"""The paper's study: a reduced run end to end, resuming, bad input."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from glshade.app.cli import main
from glshade.errors import GlshadeError
from glshade.instruments.record import Measurement
from glshade.instruments.stripes.single import measure_scene
from glshade.metrics import physics
from glshade.study import findings, plots
from glshade.study.plan import StudyPlan, case_key
from glshade.study.run import run_study
from glshade.study.store import COLUMNS, CaseResult, read_results_csv

CSV_COLUMNS = [c.name for c in COLUMNS]

TIMING = {"trace_s", "shade_s", "contours_s", "continuous_s"}
SMALL = dict(thetas=(45.0, 5.0), size=128)


def _stable(rows):
    return [{k: v for k, v in r.items() if k not in TIMING} for r in rows]


@pytest.mark.slow
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
        "## Symbols",
        "## Laws",
        "## The laws against the simulation",
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
    # every case reported done is on disk (with the rest of its geometry's cases)
    kept = {path.stem for path in (tmp_path / "resumed" / "cases").glob("*.json")}
    assert {case_key(*row.case) for row in done} <= kept and len(kept) < len(plan.cases())
    assert not (tmp_path / "resumed" / "results.csv").exists()
    resumed = run_study(plan, tmp_path / "resumed", progress=False)
    assert (resumed.skipped, resumed.computed) == (len(kept), len(plan.cases()) - len(kept))
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
        (["--thetas", "95,45"], "thetas: every value must be in (0.001, 90)"),
        (["--step", "3"], "step: must be at most one stripe period (2 mm)"),
        (["--step", "0"], "--step: must be a finite number > 0, got 0"),
        (["--sigma2s", "-1"], "sigma2s: every value must be in (0, inf)"),
        (["--workers", "-1"], '--workers: must be an integer in [0, 256] or "auto"'),
        (["--threads", "0"], "--threads: must be an integer in [1, 512]"),
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
    if "--threads" not in args:
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
    """The study shares one defect-free analysis between the defects of a geometry (every
    width and depth); its rows are nevertheless exactly what measure_scene gives for each
    scene on its own."""
    plan = StudyPlan(
        surfaces=("flat", "sphere"),
        thetas=(45.0, 5.0),
        sigma2s=(1.0, 9.0),
        dmaxs=(0.005,),
        size=256,
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


# ------------------------------------------------------------- the report, from made-up rows
EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _law_rows(plan: StudyPlan, status=None) -> list[CaseResult]:
    """Rows whose measured numbers are the closed forms (no GL): a stand-in for a run.
    ``status(case)``: the status column of each row (absent when None)."""
    rows = []
    for case in plan.cases():
        law = physics.laws(plan.scene(*case))
        visible = law.visibility_px if law.visibility_px == law.visibility_px else 0.0
        row = {name: 0 for name in CSV_COLUMNS}
        surface, theta, sigma2, dmax = case
        row.update(
            surface=surface,
            theta_deg=theta,
            sigma2_mm2=sigma2,
            dmax_mm=dmax,
            period_mm=2.0,
            visibility_px=float(round(visible)),
            visibility_continuous_px=visible,
            deflection_px=law.deflection_px,
            folded=law.folds,
            unresolved_fraction=0.0,
            noise_floor_px=None,
            status="ok",
            status_reason="",
            stripe_contrast=1.0,
            fold_ratio=law.fold_ratio,
            deflection_law_px=law.deflection_px,
            visibility_law_px=visible,
            magnification=law.magnification,
        )
        result = CaseResult.from_row(row)
        if status is not None:
            rows.append(_WithStatus(result, *status(case)))
        else:
            rows.append(result)
    return rows


class _WithStatus(dict):
    """A row with the ``status`` and ``status_reason`` columns a run may add."""

    def __init__(self, row, status, reason):
        super().__init__(dict(row.items()), status=status, status_reason=reason)

    def __getattr__(self, name):
        try:
            return self[name]
        except KeyError as error:
            raise AttributeError(name) from error


PAPER_PLAN = StudyPlan(thetas=(85.0, 45.0, 15.0, 5.0), size=256)
SYMBOL_CANDIDATES = ("Dc", "De", "f", "p", "κ", "κ_t", "κ_s", "b", "F", "m", "R", "D", "e",
                     "θ", "σ²", "σ", "dmax", "ρ", "δ")  # fmt: skip


def _report(tmp_path, rows, plan) -> str:
    return findings.write_report(rows, tmp_path, plan, []).read_text()


def test_report_defines_every_symbol_once_and_repeats_no_paragraph(tmp_path):
    report = _report(tmp_path, _law_rows(PAPER_PLAN), PAPER_PLAN)
    head, _, rest = report.partition("## Symbols")
    table, _, body = rest.partition("## Laws")
    defined = {line.split("|")[1].strip() for line in table.splitlines() if line.startswith("| ")}
    text = head + body
    for symbol in SYMBOL_CANDIDATES:
        if re.search(rf"(?<![\w]){re.escape(symbol)}(?![\w])", text):
            assert symbol in defined, symbol
    # the symbols' values are the study's: the camera's distance and the 256×256 image
    assert "| Dc | distance from the camera to the gaze point | mm | 175.6 |" in report
    assert "pixel pitch of the 256×256 image" in report
    # every law once, in the Laws section, and no paragraph twice
    assert report.count("2 κ Dc De / ((Dc + De) sin θ)") <= 2  # the fold law and its symbol
    assert report.count("Where nothing folds the deflection") == 0
    paragraphs = [
        p.strip()
        for p in re.split(r"\n", report)
        if len(p.strip()) > 60 and not p.startswith(("|", "#"))
    ]
    repeated = {p for p in paragraphs if paragraphs.count(p) > 1}
    assert not repeated, repeated
    for name in ("specification", "SPEC", "issue #"):
        assert name not in report


def test_verdicts_carry_their_numbers():
    verdicts = findings.evaluate(_law_rows(PAPER_PLAN))
    assert verdicts
    for v in verdicts:
        assert v.text.startswith(v.verdict + ": ") and re.search(r"[-+]?\d+%", v.text), v.text
    steep = [v for v in verdicts if v.finding == 4 and v.scope == "flat, dmax 5 µm"]
    assert any("σ² 1 -" in v.text and "folds at" in v.text for v in steep), steep


def test_free_form_surfaces_get_their_own_text_never_the_spheres():
    plan = StudyPlan(
        surfaces=(str(EXAMPLES / "panel.toml"), str(EXAMPLES / "saddle.toml")),
        thetas=(85.0, 45.0, 5.0),
        sigma2s=(1.0, 16.0),
        dmaxs=(0.005,),
        size=128,
    )
    text = "\n".join(findings.advice(_law_rows(plan)))
    for word in ("sphere", "cylinder", "loses every dent"):
        assert word not in text, word
    panel, saddle = text.split("**saddle**")
    assert "height map" in panel and "Concave along the plane of incidence" in panel
    assert "free-form surface" in panel and "κ_t = +" in panel
    assert "Convex along the plane of incidence" in saddle and "y = " in saddle


def test_figure_axes_name_the_runs_image_size(tmp_path, monkeypatch):
    drawn = []
    monkeypatch.setattr(plots, "_save", lambda fig, path, **kw: drawn.append(fig))
    plan = StudyPlan(surfaces=("flat",), thetas=(45.0, 5.0), sigma2s=(1.0,), size=96)
    rows = _law_rows(plan)
    plots.write_figures(rows, tmp_path, plan)
    labels = [ax.get_ylabel() for fig in drawn for ax in fig.axes if ax.get_ylabel()]
    assert labels and all("96×96" in label for label in labels), labels
    assert not any("1024" in label for label in labels)
    # the legends sit outside the data: figure legends, none on an axes
    assert all(ax.get_legend() is None for fig in drawn for ax in fig.axes)


def test_rows_not_measurable_are_left_out_of_verdicts_and_advice(tmp_path):
    plan = StudyPlan(surfaces=("flat", "sphere"), thetas=(85.0, 45.0, 15.0, 5.0), size=256)

    def unresolved(case):
        return ("unresolved", "3.1 px per period") if case[1] == 5.0 else ("ok", "")

    marked = _law_rows(plan, unresolved)
    for row in marked:  # a number nobody may judge
        if row["status"] != "ok":
            row["visibility_px"] = row["visibility_continuous_px"] = 1000.0
    kept = [r for r in _law_rows(plan) if r["theta_deg"] != 5.0]
    assert findings.advice(marked) == findings.advice(kept)
    assert [v.text for v in findings.evaluate(marked)] == [v.text for v in findings.evaluate(kept)]
    report = _report(tmp_path, marked, plan)
    assert "16 of 64 cases not measurable: stripes unresolved (16; 3.1 px per period)" in report
    # without the column every row counts
    plain = _law_rows(plan)
    assert findings.advice(plain) != findings.advice(kept)
    drawn = []
    plots._save, saved = (lambda fig, path, **kw: drawn.append(fig)), plots._save
    try:
        plots.visibility_plot(marked, "flat", 0.005, tmp_path / "v.png", (256, 256))
    finally:
        plots._save = saved
    labels = [t.get_text() for fig in drawn for legend in fig.legends for t in legend.get_texts()]
    assert "not measurable" in labels


def test_the_study_on_worker_processes_writes_the_same_rows(tmp_path, renderer):
    """Two local worker processes (each tracing and measuring whole geometries, thumbnails
    made there) write the rows and figures' inputs this process writes, number for number."""
    from glshade.measure.executors import Distribution

    plan = StudyPlan(surfaces=("flat", "sphere"), thetas=(45.0, 5.0), sigma2s=(4.0,), size=96)
    here = run_study(plan, tmp_path / "here", progress=False, renderer=renderer)
    there = run_study(
        plan, tmp_path / "there", progress=False, distribution=Distribution(workers=2)
    )
    assert there.computed == here.computed == 8
    assert _stable(read_results_csv(tmp_path / "there" / "results.csv")) == _stable(
        read_results_csv(tmp_path / "here" / "results.csv")
    )
    thumbnails = sorted(p.name for p in (tmp_path / "here" / "cases").glob("*.png"))
    assert thumbnails and thumbnails == sorted(
        p.name for p in (tmp_path / "there" / "cases").glob("*.png")
    )
    for name in thumbnails:
        assert (tmp_path / "here" / "cases" / name).read_bytes() == (
            tmp_path / "there" / "cases" / name
        ).read_bytes()


def test_a_theta_verdict_shows_its_rho_and_the_advice_s_reference():
    """Finding 4's headline carries the numbers it is decided on: a large loss (-60 %)
    with a ranked trend of ρ +0.30 does not hold, and says so with its ρ; its θ near the
    best are those the camera advice names (90 % of the best over θ, one reference); a
    series whose lowest θ could not be read names its last θ as the lowest readable."""
    thetas = (85.0, 65.0, 45.0, 25.0, 5.0)
    steep = {85.0: 10.0, 65.0: 3.0, 45.0: 9.8, 25.0: 9.9, 5.0: 4.0}  # up and down: ρ +0.30
    rows = [
        dict(
            surface=surface,
            theta_deg=t,
            sigma2_mm2=1.0,
            dmax_mm=0.005,
            visibility_px=steep[t],
            visibility_continuous_px=steep[t],
            folded=False,
            status="edge" if surface == "sphere" and t == 5.0 else "ok",
        )
        for surface in ("flat", "sphere")
        for t in thetas
    ]
    verdict = next(
        v
        for v in findings.evaluate(rows)
        if (v.finding, v.scope, v.metric) == (4, "flat, dmax 5 µm", "continuous limit")
    )
    assert verdict.verdict == findings.NOT
    assert verdict.text == (
        "does not hold: σ² 1 -60% (ρ +0.30) (θ 85° → 5°); at least 90% of its best: "
        "σ² 1 at θ 85°, 45–25°"
    )
    assert findings.best_thetas(rows, "flat", [1.0], 0.005) == [85.0, 45.0, 25.0]
    sphere = next(
        v for v in findings.evaluate(rows) if v.finding == 4 and v.scope.startswith("sphere")
    )
    assert "(θ 85° → 25°, the lowest readable)" in sphere.text
