"""A scene file's ``[measure]`` table: how its scene is measured (the instrument and its
settings). ``glshade measure``, ``optimize`` and ``sweep`` start from it, the command
line and a sweep file's ``[measure]`` override it key by key; it is the file's, not the
scene's (the scene, its dictionary and every case id are the same without it); a bad
table is one line naming the file."""

from __future__ import annotations

import json

import pytest

from glshade.app.cli import main
from glshade.instruments.pmd.settings import PmdSettings
from glshade.scene import Scene
from glshade.sweep.spec import load_spec

SCENE = "[camera]\ntheta_deg = 45.0\n[defect]\nsigma2 = 4.0\n"


def _measured(capsys, *argv: str) -> dict:
    assert main(["measure", *argv, "--size", "256", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    out.pop("seconds")
    return out


@pytest.fixture
def files(tmp_path):
    plain = tmp_path / "plain.toml"
    plain.write_text(SCENE)
    tabled = tmp_path / "tabled.toml"
    tabled.write_text(SCENE + "[measure]\nthreshold = 0.7\n")
    return plain, tabled


def test_the_table_is_the_files_not_the_scenes(files):
    plain, tabled = files
    assert Scene.load(tabled) == Scene.load(plain)
    assert Scene.load(tabled).to_dict() == Scene.load(plain).to_dict()


@pytest.mark.gl
def test_measure_starts_from_the_files_settings_and_the_command_line_wins(files, capsys):
    plain, tabled = files
    from_file = _measured(capsys, str(tabled))
    assert from_file == _measured(capsys, str(plain), "--set", "measure.threshold=0.7")
    assert from_file != _measured(capsys, str(plain))
    assert _measured(capsys, str(tabled), "--threshold", "0.5") == _measured(
        capsys, str(plain), "--threshold", "0.5"
    )


@pytest.mark.gl
def test_a_table_of_another_instrument_is_said_and_not_applied(tmp_path, files, capsys):
    plain, _ = files
    other = tmp_path / "other.toml"
    other.write_text(SCENE + '[measure]\nmethod = "pmd"\nheights = "frankot-chellappa"\n')
    out = _measured(capsys, str(plain), "--method", "paper")
    assert main(["measure", str(other), "--method", "paper", "--size", "256", "--json"]) == 0
    said = capsys.readouterr()
    assert {k: v for k, v in json.loads(said.out).items() if k != "seconds"} == out
    assert said.err.count("\n") == 1
    assert "its [measure] is phase measuring's: --method paper measures with its own" in said.err


@pytest.mark.parametrize(
    "table, words",
    [
        ("threshold = 5", "tabled.toml: measure.threshold: must be in"),
        ("heights = 'least-squares'", "measure.heights: unknown setting of method paper"),
        ("method = 'nope'", "measure.method: must be one of paper, pmd, got 'nope'"),
        ("", None),
    ],
)
def test_a_bad_table_is_one_line_naming_the_file(tmp_path, capsys, table, words):
    path = tmp_path / "tabled.toml"
    path.write_text(("measure = 3\n" + SCENE) if not table else SCENE + "[measure]\n" + table)
    assert main(["measure", str(path), "--json"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("glshade: error:")
    assert (words or "[measure] must be a table") in err


def test_a_sweep_starts_from_its_base_files_table(tmp_path, files):
    _, tabled = files
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(f'base = "{tabled.name}"\n[grid]\n"defect.dmax" = [0.003, 0.005]\n')
    assert load_spec(sweep).settings.threshold == 0.7
    sweep.write_text(sweep.read_text() + "[measure]\nthreshold = 0.3\n")
    assert load_spec(sweep).settings.threshold == 0.3
    sweep.write_text(sweep.read_text().replace("threshold = 0.3", 'method = "pmd"'))
    assert load_spec(sweep).settings == PmdSettings()  # the base's table is the stripes'


def test_a_study_says_it_does_not_read_a_surface_files_table(tmp_path, capsys):
    """A study measures every case with its own settings: a free-form surface's file
    whose ``[measure]`` sets something is said not to be read (before anything runs)."""
    panel = tmp_path / "panel.toml"
    panel.write_text('[surface]\nkind = "formula"\nexpression = "0.001 * x * z"\n')
    argv = ["paper", "--surfaces", f"flat,{panel}", "--as-sweep", str(tmp_path / "s.toml")]
    assert main(argv) == 2  # (a scene file has no sweep form: nothing runs)
    assert "its [measure] is not read" not in capsys.readouterr().err
    panel.write_text(panel.read_text() + "[measure]\nthreshold = 0.7\n")
    assert main(argv) == 2
    assert f"{panel}: its [measure] is not read by the study" in capsys.readouterr().err
