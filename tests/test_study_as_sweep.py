"""A study is a sweep specification and an instrument's report: ``glshade paper
--as-sweep FILE`` writes the study's cases as a sweep file (a linked surface axis, θ, σ²
and dmax in the study's order, its size and ``[measure]`` table; for phase measuring each
surface's fringe periods and the station's chain too), and ``glshade sweep`` of that file
measures the same scenes to the same numbers, column for column."""

from __future__ import annotations

import csv
import tomllib

import pytest

from glshade.app.cli import main
from glshade.sweep.spec import load_spec

PLAN = ["--surfaces", "flat,sphere", "--thetas", "45,15", "--sigma2s", "4", "--dmaxs",
        "0.005", "--size", "48", "--no-progress"]  # fmt: skip


def _rows(path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.mark.gl
@pytest.mark.parametrize("method, table", [("paper", "results.csv"), ("pmd", "pmd_results.csv")])
def test_the_studys_cases_swept_give_its_numbers(tmp_path, capsys, method, table):
    sweep_file, study, swept = tmp_path / "study.toml", tmp_path / "study", tmp_path / "swept"
    assert main(["paper", "--method", method, *PLAN, "--as-sweep", str(sweep_file)]) == 0
    assert "the study's 4 cases as a sweep" in capsys.readouterr().out
    assert not study.exists()  # nothing measured
    spec = load_spec(sweep_file)
    assert spec.method == method and len(spec.cases()) == 4
    assert main(["paper", "--method", method, *PLAN, "--out", str(study), "--workers", "0"]) == 0
    assert main(["sweep", str(sweep_file), "--out", str(swept), "--no-progress"]) == 0
    ours, theirs = _rows(study / table), _rows(swept / "results.csv")
    common = [key for key in ours[0] if key in theirs[0] and not key.endswith("_s")]
    assert {"status", "status_reason"} <= set(common) and len(common) > 12
    assert [row["theta_deg"] for row in ours] == [row["camera.theta_deg"] for row in theirs]
    assert [row["surface"] for row in ours] == [row["surface"] for row in theirs]
    measured = [[row[k] for k in common] for row in theirs]
    assert [[row[k] for k in common] for row in ours] == measured


def test_a_scene_file_surface_has_no_sweep_form(tmp_path, capsys):
    scene = tmp_path / "panel.toml"
    scene.write_text('[surface]\nkind = "formula"\nexpression = "0.001 * x * z"\n')
    argv = ["paper", "--surfaces", f"flat,{scene}", "--as-sweep", str(tmp_path / "s.toml")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "only the paper's surfaces have a sweep form" in err
    assert not (tmp_path / "s.toml").exists()


@pytest.mark.parametrize(
    "data",
    [
        {"size": 48, "grid": {"camera.theta_deg": [45.0, 1e-07], "defect.dmax": [0.005]}},
        {
            "grid": {"surface": [{"label": "σ", "surface.kind": "flat", "emitter.periods": [2.0]}]},
            "measure": {"method": "paper", "otsu": False, "a-b": 1, "level_from": "auto"},
        },
    ],
)
def test_a_sweep_file_reads_back_as_written(data):
    from glshade.sweep.spec import sweep_toml

    text = sweep_toml(data)
    assert tomllib.loads(text) == data
    grid = text[text.index("[grid]") :].splitlines()[1:]
    assert [line.split(" = ")[0].strip('"') for line in grid if " = " in line][
        : len(data["grid"])
    ] == [*data["grid"]]  # each axis on one line, in the order given
