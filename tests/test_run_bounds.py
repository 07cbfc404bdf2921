"""How big a run may get and how soon it starts: the count of a sweep's grid, of the
optimiser's search and of the paper's study is checked from the lengths alone (beyond
the confirmation limit it needs ``--yes``, beyond the hard limit it is refused), before
any case is made; a sweep's grid is made a chunk at a time and its table written from
the chunks.

Oracles: the refusals' lines against the counts worked out by hand; the lazy grid against
the grid listed whole (the old way); the streamed tables against the tables written in
one piece from every row at once (:func:`write_tables`). No case is rendered: an
executor that makes records by rule stands in for the engine.
"""

from __future__ import annotations

import csv
import io
import itertools
import json
from pathlib import Path
from typing import Any

import pytest

from glshade.app.cli import main
from glshade.errors import GlshadeError
from glshade.instruments.record import OUTPUT_NAMES, Measurement
from glshade.study import plan as study
from glshade.sweep import optimize as opt
from glshade.sweep import run as sweep_run
from glshade.sweep import spec as sweep_spec
from glshade.sweep import store
from glshade.sweep.run import run_sweep
from glshade.sweep.spec import (
    MAX_CASES,
    MAX_CASES_UNCONFIRMED,
    GridCases,
    SweepSpec,
    spec_from_dict,
)
from glshade.sweep.table import _cell, _csv_cell

#: 99 x 100 x 100 = 990 000 cases.
BIG_GRID = {
    "size": 8,
    "grid": {
        "camera.theta_deg": {"start": 5.0, "stop": 85.0, "num": 99},
        "defect.sigma2": {"start": 1.0, "stop": 16.0, "num": 100},
        "defect.x0": {"start": -1.0, "stop": 1.0, "num": 100},
    },
}


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    assert err.startswith("glshade: error: ") and err.count("\n") == 1, err
    return err


@pytest.fixture
def scenes_made(monkeypatch) -> list[tuple[int, ...]]:
    """The grid points whose scene a sweep spec makes, in order."""
    made: list[tuple[int, ...]] = []
    scene = SweepSpec.scene

    def counted(self, index):
        made.append(index)
        return scene(self, index)

    monkeypatch.setattr(SweepSpec, "scene", counted)
    return made


# ------------------------------------------------------------------ the sweep's count
def test_a_990000_case_grid_is_refused_without_yes_before_any_value_is_built(
    tmp_path, capsys, monkeypatch
):
    def no_axis(*args):
        raise AssertionError("an axis was built before the count was checked")

    monkeypatch.setattr(sweep_spec, "_axis", no_axis)
    path = tmp_path / "big.toml"
    path.write_text(
        'size = 8\n[grid]\n"camera.theta_deg" = { start = 5.0, stop = 85.0, num = 99 }\n'
        '"defect.sigma2" = { start = 1.0, stop = 16.0, num = 100 }\n'
        '"defect.x0" = { start = -1.0, stop = 1.0, num = 100 }\n'
    )
    assert main(["sweep", str(path), "--out", str(tmp_path / "out")]) == 2
    err = one_error_line(capsys)
    assert "the grid has 99 x 100 x 100 = 990000 cases" in err
    assert "--yes" in err and str(MAX_CASES_UNCONFIRMED) in err
    assert not (tmp_path / "out").exists()


def test_a_grid_of_exactly_the_hard_limit_needs_yes(monkeypatch):
    grid = {f"defect.{k}": {"start": 1.0, "stop": 2.0, "num": 100} for k in ("x0", "z0", "sigma2")}
    monkeypatch.setattr(sweep_spec, "_axis", None)  # never reached: the count comes first
    with pytest.raises(GlshadeError) as info:
        spec_from_dict({"grid": grid}, yes=False)
    assert "the grid has 100^3 = 1000000 cases (more than 5000); add --yes" in str(info.value)


@pytest.mark.parametrize(
    "grid, words",
    [
        (
            {"camera.theta_deg": {"start": 5, "stop": 85, "num": 1001}, "defect.x0": [0.0] * 1000},
            f"the grid has 1001 x 1000 = 1001000 cases; at most {MAX_CASES} are allowed",
        ),
        (
            {"camera.theta_deg": {"start": 5.0, "stop": 85.0, "step": 1e-300}},
            f"step: 1e-300 from 5 to 85 makes more than {MAX_CASES} values",
        ),
        (
            {"camera.theta_deg": {"start": -1e308, "stop": 1e308, "step": 1.0}},
            f"step: 1 from -1e+308 to 1e+308 makes more than {MAX_CASES} values",
        ),
    ],
)
def test_grids_beyond_the_hard_limit_are_refused_even_with_yes(grid, words, monkeypatch):
    monkeypatch.setattr(sweep_spec, "_axis", None)  # never reached: the count comes first
    with pytest.raises(GlshadeError) as info:
        spec_from_dict({"grid": grid}, yes=True)
    assert words in str(info.value) and "\n" not in str(info.value)


# ------------------------------------------------------------------ the lazy grid
def test_the_first_case_of_a_990000_case_grid_makes_one_scene(scenes_made):
    spec = spec_from_dict(BIG_GRID, yes=True)
    assert len(scenes_made) <= 99 + 100 + 100  # each axis's values checked once
    scenes_made.clear()
    cases = spec.cases()
    assert isinstance(cases, GridCases) and len(cases) == spec.count == 990_000
    first = next(iter(cases))
    assert first.index == (0, 0, 0) and scenes_made == [(0, 0, 0)]
    last = cases[-1]
    assert last.index == (98, 99, 99) and len(scenes_made) == 2
    assert (last.scene.camera.theta_deg, last.scene.defect.x0) == (85.0, 1.0)
    assert cases[123_456].index == (12, 34, 56)
    chunk = next(cases.chunks(first=16))
    assert len(chunk) == 16 and len(scenes_made) == 3 + 16


def test_the_lazy_grid_is_the_grid_listed_whole():
    spec = spec_from_dict(
        {
            "size": 16,
            "grid": {
                "camera.theta_deg": [45, 15, 30],
                "defect.sigma2": {"start": 1.0, "stop": 4.0, "num": 2},
                "surface": [
                    {"label": "flat", "surface.kind": "flat"},
                    {"label": "sphere", "surface.kind": "sphere", "emitter.period": 10.0},
                ],
            },
        }
    )
    cases = spec.cases()
    listed = [spec.point(index) for index in itertools.product(range(3), range(2), range(2))]
    assert list(cases) == listed  # the old spec.cases(): every point, first axis outermost
    assert [cases[n] for n in range(len(cases))] == listed
    assert cases[-1] == listed[-1] and cases[2:5] == listed[2:5] and cases[:1] == listed[:1]
    assert [point for chunk in cases.chunks(first=2, most=4) for point in chunk] == listed
    assert [len(chunk) for chunk in cases.chunks(first=2, most=4)] == [2, 4, 4, 2]
    with pytest.raises(IndexError):
        cases[12]


# ------------------------------------------------------------------ the streamed run
class RuleExecutor:
    """Records by rule, never rendered: status ``ok`` (and a noise floor) at θ below 40°,
    ``outside`` (and its reason) above; the number of cases of each call."""

    def __init__(self) -> None:
        self.calls: list[int] = []

    def rows(self, cases, settings, images):
        self.calls.append(len(cases))
        for case in cases:
            theta = case.scene.camera.theta_deg
            ok = theta < 40.0
            values = dict.fromkeys(OUTPUT_NAMES, 0.0)
            values.update(
                visibility_px=float(round(theta) % 3),
                islands=int(theta),
                folded=False,
                noise_floor_px=0.25 if ok else None,
                status="ok" if ok else "outside",
                status_reason=None if ok else "the dent is not seen",
            )
            yield case.key, Measurement.from_row(values), None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return None


@pytest.fixture
def rule_executor(monkeypatch) -> RuleExecutor:
    executor = RuleExecutor()
    monkeypatch.setattr(sweep_run, "open_executor", lambda distribution, renderer: executor)
    return executor


class Stop(Exception):
    pass


def test_a_990000_case_sweep_measures_its_first_case_after_one_chunk(
    tmp_path, rule_executor, scenes_made
):
    spec = spec_from_dict(BIG_GRID, yes=True)
    scenes_made.clear()
    with pytest.raises(GlshadeError, match="add --yes"):
        run_sweep(spec, tmp_path / "refused")
    assert not (tmp_path / "refused").exists() and not scenes_made

    def stop(row) -> None:
        raise Stop

    with pytest.raises(Stop):
        run_sweep(spec, tmp_path / "out", yes=True, on_row=stop)
    assert len(scenes_made) == 16 and rule_executor.calls == [16]  # the first chunk only
    assert len(list((tmp_path / "out" / "cases").glob("*.json"))) == 1
    left = {p.name for p in (tmp_path / "out").iterdir()}
    assert left == {"cases", "sweep.json", ".glshade.lock"}  # no table, no temporary file


def streamed_spec() -> SweepSpec:
    """40 cases: θ across the rule's 40° (two kinds of rows), in chunks of 16 and 24."""
    return spec_from_dict(
        {
            "size": 16,
            "grid": {
                "camera.theta_deg": [55, 45, 35, 25, 15],
                "defect.sigma2": [1.0, 4.0, 9.0, 16.0],
                "surface": [
                    {"label": "flat", "surface.kind": "flat"},
                    {"label": "sphere", "surface.kind": "sphere", "emitter.period": 10.0},
                ],
            },
        }
    )


def write_tables(out_dir: Path, spec: SweepSpec, rows: list[dict[str, Any]]) -> None:
    """``results.parquet`` (the manifest in its metadata) and ``results.csv`` of ``rows``,
    written in one piece: each column's type inferred from all of its values at once (an
    integer column with a fractional value a float column, a column of only empty cells a
    float column)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    columns = ["case_id", *spec.columns, *store.output_names(spec.method)]
    types = []
    for name in columns:
        values = [_cell(row.get(name)) for row in rows if row.get(name) is not None]
        kind = pa.array(values).type if values else pa.float64()
        if pa.types.is_integer(kind) and any(isinstance(v, float) for v in values):
            kind = pa.float64()
        types.append(pa.field(name, kind))
    table = pa.Table.from_pylist(
        [{name: _cell(row.get(name)) for name in columns} for row in rows],
        schema=pa.schema(types),
    )
    table = table.replace_schema_metadata({b"glshade": json.dumps(spec.manifest()).encode()})
    buffer = io.BytesIO()
    pq.write_table(table, buffer)
    (out_dir / store.PARQUET).write_bytes(buffer.getvalue())
    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({name: _csv_cell(row.get(name)) for name in columns})
    (out_dir / store.CSV).write_text(text.getvalue())


def written_whole(spec: SweepSpec, out: Path, where: Path) -> Path:
    """The tables :func:`write_tables` writes from every row of ``out``'s cases."""
    where.mkdir()
    records = store.finished(out, [c.case_id for c in spec.cases()])
    write_tables(where, spec, store.table_rows(spec, list(spec.cases()), records))
    return where


def test_the_streamed_table_is_the_table_written_whole(tmp_path, rule_executor):
    spec = streamed_spec()
    out = tmp_path / "out"
    result = run_sweep(spec, out)
    assert rule_executor.calls == [16, 24]  # θ 55, 45 (outside: no noise floor); 35 to 15
    assert (result.cases, result.computed, result.skipped) == (40, 40, 0)
    assert result.statuses == {"outside": 16, "ok": 24}
    whole = written_whole(spec, out, tmp_path / "whole")
    for name in (store.PARQUET, store.CSV):
        assert (out / name).read_bytes() == (whole / name).read_bytes()
    assert store.read_table(out) == result.rows and len(result.rows) == 40
    again = run_sweep(spec, out)
    assert (again.computed, again.skipped) == (0, 40) and rule_executor.calls == [16, 24]
    assert again.rows == result.rows
    assert sorted(p.name for p in out.iterdir()) == [
        ".glshade.lock", "cases", "results.csv", "results.parquet", "sweep.json"
    ]  # fmt: skip


def test_a_long_table_is_written_in_row_groups_of_the_same_rows(
    tmp_path, rule_executor, monkeypatch
):
    import pyarrow.parquet as pq

    from glshade.sweep import table

    monkeypatch.setattr(table, "ROWS_PER_GROUP", 20)
    spec = streamed_spec()
    out = tmp_path / "out"
    out.mkdir()
    left = out / ".results.csv.abcd1234.tmp"  # a killed run's temporary table
    left.write_text("half a table")
    (out / "notes.txt").write_text("kept")
    run_sweep(spec, out)
    whole = written_whole(spec, out, tmp_path / "whole")
    assert pq.ParquetFile(out / store.PARQUET).num_row_groups == 2  # the chunks of 16, 24
    assert pq.read_schema(out / store.PARQUET) == pq.read_schema(whole / store.PARQUET)
    assert (
        pq.read_schema(out / store.PARQUET).metadata
        == pq.read_schema(whole / store.PARQUET).metadata
    )
    assert store.read_table(out) == store.read_table(whole)
    assert (out / store.CSV).read_bytes() == (whole / store.CSV).read_bytes()
    assert not left.exists() and (out / "notes.txt").read_text() == "kept"


# ------------------------------------------------------------------ the optimiser's count
THE_TESTERS_FAMILY = "defect.sigma2=1..16,defect.dmax=0.003..0.005,defect.x0=-1..1,defect.z0=-1..1"


def test_the_testers_family_of_16777216_dents_is_refused_before_any_member(capsys, monkeypatch):
    def no_members(axes):
        raise AssertionError("the family was listed before its count was checked")

    monkeypatch.setattr(opt, "family_members", no_members)
    argv = ["optimize", "--over", "camera.theta_deg", "--family", THE_TESTERS_FAMILY]
    assert main([*argv, "--family-points", "64", "--yes"]) == 2
    err = one_error_line(capsys)
    assert (
        "64^4 = 16777216 dents per viewpoint x 39 viewpoints (9 on the grid + at most 30 "
        f"refining) = 654311424 cases; at most {MAX_CASES} are allowed"
    ) in err


def test_a_search_beyond_the_confirmation_limit_needs_yes(capsys, tmp_path):
    plot = tmp_path / "objective.png"
    argv = ["optimize", "--over", "camera.theta_deg,camera.azimuth_deg=0..90", "--grid", "60"]
    assert main([*argv, "--refine", "0", "--family", "defect.sigma2=1|4", "--plot", str(plot)]) == 2
    assert (
        "--family/--over: 2 dents per viewpoint x 3600 viewpoints (3600 on the grid + at most 0 "
        "refining) = 7200 cases (more than 5000); add --yes to run it"
    ) in one_error_line(capsys)
    assert not plot.exists()
    dims = opt.parse_over("camera.theta_deg,camera.azimuth_deg=0..90")
    axes = opt.parse_family_axes("defect.sigma2=1..16,defect.dmax=1um..5um", points=10)
    assert opt.check_cases(dims, axes, None, 30, yes=True) == 100 * (49 + 30)
    with pytest.raises(GlshadeError) as info:
        opt.check_cases(dims, axes, None, 30, yes=False)
    assert str(info.value) == (
        "--family/--over: 10 x 10 = 100 dents per viewpoint x 79 viewpoints (49 on the grid + "
        f"at most 30 refining) = 7900 cases (more than {MAX_CASES_UNCONFIRMED}); add --yes to "
        "run it"
    )
    assert opt.check_cases(dims, (), 3, 0, yes=False) == 9
    with pytest.raises(GlshadeError, match=r"values must not repeat, got 1\|1\|4"):
        opt.parse_family_axes("defect.sigma2=1|1|4")


def test_the_objective_measures_in_chunks_and_keeps_numbers_only(monkeypatch):
    import numpy as np

    from glshade.scene import paper_scene

    base = paper_scene().with_size(16)
    dims = (opt.Dimension("camera.theta_deg", 15.0, 55.0),)
    family = opt.parse_family("defect.sigma2=1|4|9")
    points = np.array([[15.0], [25.0], [35.0], [45.0], [55.0]])
    whole = opt.SceneObjective(base, dims, family, None, "paper", RuleExecutor())
    expected = whole(points)
    monkeypatch.setattr(opt, "CHUNK_CASES", 4)
    executor = RuleExecutor()
    chunked = opt.SceneObjective(base, dims, family, None, "paper", executor)
    for got, want in zip(chunked(points), expected, strict=True):
        np.testing.assert_array_equal(got, want)
    assert executor.calls == [4, 4, 4, 3] and chunked.cases == 15
    assert len(chunked.unreadable) == 6  # θ 45 and 55 are outside, for 3 dents each
    chunked(points)
    assert executor.calls[-4:] == [0, 0, 0, 0]  # measured once


# ------------------------------------------------------------------ the study's count
def thetas(n: int) -> str:
    return ",".join(f"{89.9 - i * 80.0 / n:.6f}" for i in range(n))


@pytest.mark.parametrize("method", ["paper", "pmd"])
def test_a_study_of_5000_thetas_is_refused_before_out_is_touched(tmp_path, capsys, method):
    out = tmp_path / "study"
    assert main(["paper", "--thetas", thetas(5000), "--out", str(out), "--method", method]) == 2
    err = one_error_line(capsys)
    assert (
        "3 surfaces x 5000 thetas x 4 sigma2s x 2 dmaxs = 120000 cases; at most "
        f"{study.MAX_STUDY_CASES} are allowed"
    ) in err
    argv = ["paper", "--thetas", thetas(1000), "--out", str(out), "--method", method]
    assert main(argv) == 2
    err = one_error_line(capsys)
    assert "1000 thetas x 4 sigma2s x 2 dmaxs = 24000 cases (more than 5000); add --yes" in err
    assert not out.exists()


def test_the_study_counts_every_list_and_names_a_repeat_in_a_short_line(capsys, tmp_path):
    out = tmp_path / "study"
    sigma2s = ",".join(str(1 + i) for i in range(study.MAX_SIGMA2S))
    argv = ["paper", "--surfaces", "flat", "--thetas", thetas(10), "--out", str(out)]
    assert main([*argv, "--sigma2s", sigma2s, "--dmaxs", "1um,2um,3um,4um,5um,6um,7um,8um"]) == 2
    assert "1 surfaces x 10 thetas x 64 sigma2s x 8 dmaxs = 5120 cases" in one_error_line(capsys)
    assert main([*argv, "--sigma2s", f"{sigma2s},65"]) == 2
    assert "sigma2s: at most 64 values (the image grids draw a row for each), got 65" in (
        one_error_line(capsys)
    )
    assert main([*argv, "--dmaxs", "3um,3um"]) == 2
    err = one_error_line(capsys)
    assert "dmaxs: values must not repeat, got 0.003 twice" in err
    assert main(["paper", "--thetas", f"{thetas(3000)},1.0,2.0", "--out", str(out)]) == 2
    err = one_error_line(capsys)
    assert "thetas: must be strictly decreasing" in err and "(3002 values)" in err
    assert len(err) < 400 and not out.exists()


def test_the_study_plan_refuses_beyond_its_limit_before_any_scene(monkeypatch):
    def no_scene(*args):
        raise AssertionError("a scene was made before the count was checked")

    monkeypatch.setattr(study, "case_scene", no_scene)
    with pytest.raises(GlshadeError, match="at most 100000 are allowed"):
        study.StudyPlan(thetas=tuple(89.0 - i * 1e-4 for i in range(5000)))
    assert study.MAX_CASES_UNCONFIRMED == MAX_CASES_UNCONFIRMED  # the sweep's


def test_the_paper_plan_counts_without_listing():
    plan = study.StudyPlan(size=64)
    assert plan.count == len(plan.cases()) == 216
    study.check_size(plan, yes=False)
