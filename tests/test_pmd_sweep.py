"""Phase-measuring deflectometry in sweeps, on Dask and in the optimiser (docs/sweeps.md).

Oracles: a case is a pure function of its scene and settings, so a pmd sweep's table must
equal :func:`glshade.instruments.pmd.station.measure_pmd_scene` case by case, and the Dask table the
in-process one; case ids against the documented identity (hashed by hand here) and, for
the paper's metric, against ids computed before phase measuring reached the sweeps; the
optimiser's status handling against a stub executor whose records are known by
construction (the best number unreadable), and on real scenes whose dent leaves the image.
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import asdict, fields
from pathlib import Path

import numpy as np
import pytest

from glshade.app.cli import main
from glshade.errors import GlshadeError
from glshade.instruments.base import Case
from glshade.instruments.pmd.settings import PMD_VERSION, PmdSettings
from glshade.instruments.pmd.station import measure_pmd_scene
from glshade.instruments.record import (
    PMD_OUTPUT_NAMES,
    Measurement,
    PmdMeasurement,
    columns_markdown,
)
from glshade.measure.executors import Distribution
from glshade.measure.single import as_method
from glshade.measure.where import open_executor
from glshade.scene import paper_scene
from glshade.sweep import optimize as opt
from glshade.sweep import store
from glshade.sweep.run import run_sweep
from glshade.sweep.spec import load_spec, spec_from_dict

ROOT = Path(__file__).resolve().parents[1]
SENSOR = {"sensor.full_well_e": [10000.0]}
PMD = {
    "size": 64,
    "metric": {"method": "pmd"},
    "grid": {"camera.theta_deg": [45, 20], "emitter.shifts": [3, 4], **SENSOR},
}
#: The ids of ``PAPER``'s cases: those main computed before sweeps knew phase measuring
#: (298960e17eefa6a5, …) under metric version 2, as version 3 (a scene without a dent is
#: ``outside``; the sensor's black level) names them. Only the version changed them.
PAPER = {"size": 64, "grid": {"camera.theta_deg": [45, 15], "defect.sigma2": [1.0, 4.0]}}
PAPER_IDS = ["44507663e86ea9c1", "61a22fd827fbc826", "af7497805db02481", "926e5563e17ee9eb"]


def pmd_spec(**changes):
    return spec_from_dict({**PMD, **changes})


# ------------------------------------------------------------------ the sweep file
def test_the_measure_table_is_the_metric_table():
    """``[measure]`` (the table's name) and ``[metric]`` (its former name) read the same."""
    table = dict(PMD["metric"])
    rest = {key: value for key, value in PMD.items() if key != "metric"}
    spec = spec_from_dict({**rest, "measure": table})
    assert spec.settings == pmd_spec().settings and spec.method == "pmd"
    assert [c.case_id for c in spec.cases()] == [c.case_id for c in pmd_spec().cases()]
    with pytest.raises(GlshadeError, match=r"<sweep>: measure\.heights: must be one of"):
        spec_from_dict({**rest, "measure": {**table, "heights": "x"}})


def test_paper_case_ids_are_unchanged():
    spec = spec_from_dict(PAPER)
    assert spec.method == "paper" and spec.manifest()["method"] == "paper"
    assert [c.case_id for c in spec.cases()] == PAPER_IDS


def test_a_pmd_sweep_shows_the_fringes_and_hashes_its_settings():
    spec = pmd_spec()
    assert spec.method == "pmd" and isinstance(spec.settings, PmdSettings)
    cases = spec.cases()
    assert len(cases) == spec.count == 4
    assert all(c.scene.active.emitter.measured_by == "pmd" for c in cases)
    assert [c.scene.emitter.shifts for c in cases] == [3, 4, 3, 4]
    assert [c.scene.camera.theta_deg for c in cases] == [45.0, 45.0, 20.0, 20.0]
    assert all(c.scene.sensor.full_well_e == 10000.0 and c.scene.camera.width == 64 for c in cases)
    assert spec.columns == ("camera.theta_deg", "emitter.shifts", "sensor.full_well_e")
    for case in cases:  # the documented identity: scene, method, settings, version
        text = json.dumps(
            {
                "scene": case.scene.to_dict(),
                "method": "pmd",
                "pmd": asdict(PmdSettings()),
                "pmd_version": PMD_VERSION,
            },
            sort_keys=True,
            default=str,
        )
        assert case.case_id == hashlib.sha256(text.encode()).hexdigest()[:16]
    assert len({c.case_id for c in cases}) == 4
    other = pmd_spec(metric={"method": "pmd", "grid_points": 64}).cases()
    assert not {c.case_id for c in cases} & {c.case_id for c in other}
    manifest = spec.manifest()
    assert manifest["method"] == "pmd" and manifest["pmd_version"] == PMD_VERSION
    assert manifest["metric"] == asdict(PmdSettings()) and "metric_version" not in manifest


def test_the_base_scenes_emitter_chooses_the_default_method(tmp_path):
    fringes = as_method(paper_scene(), "pmd")
    fringes.save(tmp_path / "station.toml")
    (tmp_path / "s.toml").write_text(
        'base = "station.toml"\nsize = 48\n[grid]\n"camera.theta_deg" = [45]\n'
    )
    assert load_spec(tmp_path / "s.toml").method == "pmd"
    (tmp_path / "p.toml").write_text(
        'base = "station.toml"\n[metric]\nmethod = "paper"\n[grid]\n"camera.theta_deg" = [45]\n'
    )
    paper = load_spec(tmp_path / "p.toml")
    assert paper.method == "paper"
    assert paper.cases()[0].scene.active.emitter.measured_by == "paper"
    example = load_spec(ROOT / "examples" / "pmd_sweep.toml")
    assert example.method == "pmd" and example.count == 15
    assert example.cases()[0].scene.sensor.on


@pytest.mark.parametrize(
    "changes, words",
    [
        ({"metric": {"method": "pmd", "step_mm": 0.5}}, "metric.step_mm: unknown setting"),
        ({"metric": {"method": "laser"}}, "metric.method: must be one of paper, pmd, got 'laser'"),
        (
            {"metric": {"method": "pmd", "grid_points": "a"}},
            "grid_points: must be an integer in [16, 1024]",
        ),
        (
            {"metric": {"method": "pmd", "grid_points": 4}},
            "grid_points: must be an integer in [16, 1024], got 4",
        ),
        (
            {"metric": {"method": "pmd", "heights": 3}},
            "heights: must be one of least-squares, frankot-chellappa",
        ),
        ({"metric": {"method": "pmd", "modulation_share": True}}, "metric.modulation_share"),
        (
            {"grid": {"surface": [{"label": "s", "emitter.kind": "stripes"}]}},
            "is measured by paper, not by this sweep's method pmd",
        ),
        ({"grid": {"emitter.periods": [[2.0, 16.0, 128.0]]}}, "grid.emitter.periods"),
        ({"grid": {"emitter.shifts": [2]}}, "grid.emitter.shifts"),
        ({"measure": {"method": "pmd"}}, "[measure] and [metric] are one table"),
    ],
)
def test_bad_pmd_sweep_files_are_one_line(changes, words):
    with pytest.raises(GlshadeError) as info:
        pmd_spec(**changes)
    assert words in str(info.value) and "\n" not in str(info.value)
    if "unknown setting" in words:
        names = ", ".join(["method", *(f.name for f in fields(PmdSettings))])
        assert f"allowed: {names}" in str(info.value)


# ------------------------------------------------------------------ the table
@pytest.fixture(scope="module")
def pmd_table(tmp_path_factory, _session_renderer):
    out = tmp_path_factory.mktemp("pmd_sweep")
    return out, run_sweep(pmd_spec(), out, renderer=_session_renderer)


def test_the_table_holds_the_pmd_columns_and_equals_measure_pmd(pmd_table, renderer):
    out, result = pmd_table
    spec = pmd_spec()
    rows = store.read_table(out)
    assert rows == result.rows and result.computed == 4
    assert list(rows[0]) == ["case_id", *spec.columns, *PMD_OUTPUT_NAMES]
    header = (out / "results.csv").read_text().splitlines()[0]
    assert header == ",".join(["case_id", *spec.columns, *PMD_OUTPUT_NAMES])
    for case, row in zip(spec.cases(), rows, strict=True):
        direct = PmdMeasurement.of(case.scene, measure_pmd_scene(renderer, case.scene))
        assert row == {"case_id": case.case_id, **spec.swept_values(case), **direct.outputs()}
        assert row["status"] == "ok" and row["pmd_snr"] > 10.0
    # the phase steps' noise falls as 1 / sqrt(N) (the record's own prediction agrees)
    noise = {row["emitter.shifts"]: row["pmd_noise_mm"] for row in rows[:2]}
    assert noise[4] / noise[3] == pytest.approx(math.sqrt(3 / 4), rel=0.1)


def test_case_files_read_back_as_pmd_records_and_resume(pmd_table, renderer, tmp_path):
    out, result = pmd_table
    first = pmd_spec().cases()[0].case_id
    record = store.finished(out, [first], "pmd")[first]
    assert isinstance(record, PmdMeasurement) and record.render_s > 0.0
    assert record.outputs() == {k: result.rows[0][k] for k in PMD_OUTPUT_NAMES}
    assert store.finished(out, [first], "paper") == {}  # another instrument's record
    copy = tmp_path / "copy"
    for path in out.rglob("*.json"):
        target = copy / path.relative_to(out)
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(path.read_bytes())
    (copy / "cases" / f"{first}.json").unlink()
    again = run_sweep(pmd_spec(), copy, renderer=renderer)
    assert again.computed == 1 and again.skipped == 3 and again.rows == result.rows
    manifest = json.loads((copy / "sweep.json").read_text())
    assert manifest["method"] == "pmd"


def test_a_paper_sweep_is_refused_in_a_pmd_directory(pmd_table, tmp_path, capsys):
    out, _ = pmd_table
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    (tmp_path / "s.toml").write_text('size = 64\n[grid]\n"camera.theta_deg" = [45]\n')
    assert main(["sweep", str(tmp_path / "s.toml"), "--out", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "another method (pmd there, paper here)" in err and err.count("\n") == 1
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before


def test_a_paper_sweep_written_before_the_method_was_recorded_resumes(tmp_path, renderer):
    spec = spec_from_dict({"size": 48, "grid": {"camera.theta_deg": [45]}})
    run_sweep(spec, tmp_path, renderer=renderer)
    manifest = json.loads((tmp_path / "sweep.json").read_text())
    del manifest["method"]
    (tmp_path / "sweep.json").write_text(json.dumps(manifest))
    again = run_sweep(spec, tmp_path, renderer=renderer)
    assert again.computed == 0 and again.skipped == 1
    case_id = spec.cases()[0].case_id
    record = store.finished(tmp_path, [case_id])[case_id]
    assert isinstance(record, Measurement) and record.trace_s > 0.0


def test_images_of_a_pmd_sweep_are_the_first_recorded_frame(tmp_path, renderer):
    import cv2

    from glshade.files import quantize

    spec = pmd_spec(size=48, grid={"camera.theta_deg": [45], **SENSOR}, output={"images": True})
    run_sweep(spec, tmp_path, renderer=renderer)
    (case,) = spec.cases()
    png = cv2.imread(str(tmp_path / "images" / f"{case.case_id}.png"), cv2.IMREAD_UNCHANGED)
    frame = measure_pmd_scene(renderer, case.scene).maps.recorded[0]
    assert png.shape == (48, 48) and (png == quantize(frame, 8)).all()
    assert png.std() > 10  # the finest fringes, not a flat grey


def test_the_docs_hold_the_generated_pmd_columns():
    page = (ROOT / "docs" / "sweeps.md").read_text()
    assert columns_markdown(store.outputs("pmd")) in page
    assert columns_markdown(store.outputs("paper")) in page


# ------------------------------------------------------------------ the CLI and Dask
@pytest.mark.slow
def test_two_workers_give_the_same_pmd_table_and_unreadable_cases_are_counted(
    tmp_path, renderer, capsys
):
    """One Dask run (its start-up is slow): the table equals the in-process one, and a dent
    moved out of view is counted by its status."""
    data = {
        **PMD,
        "grid": {
            "camera.theta_deg": [45, 20],
            "defect.x0": [0.0, 40.0],  # 40 mm: beyond the field of view at every elevation
            **SENSOR,
        },
    }
    path = tmp_path / "pmd.toml"
    path.write_text(
        'size = 64\n[metric]\nmethod = "pmd"\n[grid]\n'
        + "".join(f'"{key}" = {json.dumps(value)}\n' for key, value in data["grid"].items())
    )
    local = run_sweep(spec_from_dict(data), tmp_path / "local", renderer=renderer)
    code = main(
        ["sweep", str(path), "--out", str(tmp_path / "dask"), "--workers", "2", "--batch", "1"]
        + ["--no-progress"]
    )
    out = capsys.readouterr().out
    assert code == 0 and "4 cases measured by pmd (4 measured" in out
    assert "not measurable: 2 outside (the status and status_reason columns say why)" in out
    assert store.read_table(tmp_path / "dask") == local.rows
    assert [row["status"] for row in local.rows] == ["ok", "outside", "ok", "outside"]


# ------------------------------------------------------------------ the optimiser
class StubExecutor:
    """Records known by construction: ``snr(theta)`` peaks at 60° but is unreadable
    (``edge``) above 55°; the noise is least at 70° (unreadable there too). A family's
    member ``defect.dmax`` scales the SNR (the deeper, the higher)."""

    def __init__(self) -> None:
        self.calls: list[int] = []

    def rows(self, cases, settings, images):
        assert isinstance(settings, PmdSettings) and not images
        self.calls.append(len(cases))
        for case in cases:
            scene = case.scene
            assert scene.active.emitter.measured_by == "pmd"
            theta = scene.camera.theta_deg
            snr = (100.0 - abs(theta - 60.0)) * scene.defect.dmax / 0.005
            noise = 0.003 + 1e-5 * abs(theta - 70.0) + 1e-3 * (scene.defect.dmax - 0.003)
            status = "edge" if theta > 55.0 else "ok"
            yield case.key, _record(snr, noise, status), None


def _record(snr: float, noise: float, status: str) -> PmdMeasurement:
    values = {name: 0.0 for name in PMD_OUTPUT_NAMES}
    values.update(pmd_snr=snr, pmd_noise_mm=noise, status=status, unwrap_failures=0)
    values.update(status_reason="" if status == "ok" else "the dent's region touches the border")
    return PmdMeasurement.from_row(values)


def _stub_search(metric: str, family=None, refine: int = 0):
    base = paper_scene().with_size(48).with_value("sensor.full_well_e", 10000.0)
    dims = (opt.Dimension("camera.theta_deg", 10.0, 82.0),)  # steps of 9°
    return opt.optimize_scene(
        base, dims, family or [{}], metric=metric, executor=StubExecutor(),
        grid_points=9, refine_evaluations=refine,
    )  # fmt: skip


def test_the_optimiser_never_picks_an_unreadable_pmd_point():
    result = _stub_search("pmd_snr", refine=6)
    evaluated = result.points[:, 0]
    ok = evaluated <= 55.0
    assert (~ok[: result.grid_count]).sum() == 3  # 64°, 73°, 82° of the grid
    assert result.evaluations > result.grid_count  # the refinement ran, into the edge too
    assert result.unmeasurable == int((~ok).sum()) and result.unmeasurable_statuses == {
        "edge": int((~ok).sum())
    }
    # the best readable point of all evaluated (64° scores more but is at an edge)
    best = evaluated[ok][np.argmax(100.0 - np.abs(evaluated[ok] - 60.0))]
    assert result.optimum["camera.theta_deg"] == pytest.approx(best, abs=1e-4)
    assert result.optimum["camera.theta_deg"] <= 55.0
    assert result.value == pytest.approx(100.0 - abs(best - 60.0))
    assert np.isnan(result.values[~ok]).all() and np.isfinite(result.values[ok]).all()
    summary = result.summary()
    assert summary["pmd_snr"] == summary["value"] == result.value
    assert summary["unmeasurable_cases"] == result.unmeasurable and summary["maximised"] is True
    assert "visibility_px" not in summary and summary["evaluations"] == result.evaluations


def test_the_pmd_noise_is_minimised_and_the_family_takes_the_worst_case():
    family = opt.parse_family("defect.dmax=0.003|0.005")
    snr = _stub_search("pmd_snr", family)
    assert snr.optimum["camera.theta_deg"] == 55.0
    assert snr.value == pytest.approx(95.0 * 0.003 / 0.005)  # the shallower dent's
    noise = _stub_search("pmd_noise_mm", family)
    assert noise.optimum["camera.theta_deg"] == 55.0  # 64°, 73° are quieter but unreadable
    assert noise.value == pytest.approx(0.003 + 1.5e-4 + 2e-6)  # the deeper dent's, the worst
    assert noise.summary()["maximised"] is False


def test_optimize_pmd_snr_on_real_scenes_skips_a_dent_out_of_the_image(capsys):
    """The dent 20 mm from the gaze point along z: at 45° and above its region touches the
    image's border (status edge) at 64²; the search keeps to the views that see it whole."""
    code = main(
        ["optimize", "--over", "camera.theta_deg=15..75", "--metric", "pmd_snr", "--size", "64"]
        + ["--grid", "5", "--refine", "3", "--set", "sensor.full_well_e=10000"]
        + ["--set", "defect.z0=20", "--json"]
    )
    summary = json.loads(capsys.readouterr().out)
    assert code == 0
    assert set(summary) >= {"optimum", "pmd_snr", "value", "evaluations", "unmeasurable_cases"}
    theta = summary["optimum"]["camera.theta_deg"]
    assert 15.0 <= theta < 45.0 and summary["unmeasurable_cases"] >= 3
    assert summary["unmeasurable_statuses"]["edge"] >= 3
    scene = as_method(paper_scene(), "pmd").with_size(64)
    scene = scene.with_values(
        [("sensor.full_well_e", 10000.0), ("defect.z0", 20.0), ("camera.theta_deg", theta)]
    )
    with open_executor(Distribution()) as executor:
        ((_, record, _),) = executor.rows([Case("best", scene)], PmdSettings(), False)
    assert record.status == "ok" and record.pmd_snr == pytest.approx(summary["pmd_snr"], rel=0.02)


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--metric", "pmd_snr", "--step", "0.5"], "--step: belongs to the paper's stripe metric"),
        (["--metric", "pmd_depth_um", "--threshold", "0.4"], "--threshold: belongs to the paper"),
        (["--metric", "pmd_snr"], "--metric pmd_snr: needs a sensor"),
        (["--metric", "pmd_noise_mm"], "--metric pmd_noise_mm: needs a sensor"),
        (["--metric", "pmd_nope"], "invalid choice: 'pmd_nope'"),
        (
            ["--metric", "paper", "--heights", "least-squares"],
            "--heights: belongs to phase measuring",
        ),
        (
            ["--metric", "pmd_depth_um", "--modulation-share", "2"],
            "--modulation-share: must be in (0, 1), got 2",
        ),
    ],
)
def test_bad_optimize_input_is_one_line(argv, words, capsys, tmp_path):
    plot = tmp_path / "objective.png"
    code = main(
        ["optimize", "--over", "camera.theta_deg", "--size", "48", "--plot", str(plot)] + argv
    )
    err = capsys.readouterr().err
    assert code == 2 and words in err and err.count("\n") == 1
    assert not plot.exists()
