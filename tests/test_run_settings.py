"""Where the cases run (``run.*``), declared once: the flags, their help, their one-line
errors and the generated docs come from :class:`glshade.run_settings.RunSettings`."""

from __future__ import annotations

import pytest

from glshade.app.cli import main
from glshade.errors import SceneError
from glshade.params import declared_params
from glshade.run_settings import RunSettings


def test_the_declarations_check_their_values():
    assert RunSettings() == RunSettings(None, None, 10.0, 2, 16, None)
    for field, value in (("threads", 0), ("batch", 5000), ("connect_timeout", 0.0)):
        with pytest.raises(SceneError, match=f"run.{field}: must be"):
            RunSettings(**{field: value})


@pytest.mark.parametrize(
    "argv, words",
    [
        (["sweep", "s.toml", "--batch", "0"], "--batch: must be an integer in [1, 4096], got 0"),
        (["sweep", "s.toml", "--workers", "auto"], "--workers: must be an integer in [0, 256]"),
        (["sweep", "s.toml", "--connect-timeout", "0"], "--connect-timeout: must be in (0, 3600]"),
        (["render", "--device", "-1", "-o", "x.png"], "--device: must be an integer in [0, 1024]"),
        (["info", "--device", "one"], "--device: must be an integer in [0, 1024], got one"),
    ],
)
def test_a_bad_run_setting_is_one_line_naming_its_flag(tmp_path, monkeypatch, capsys, argv, words):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err
    assert not any(tmp_path.iterdir())


def _help(command: str, capsys) -> str:
    assert main([command, "--help"]) == 0
    return " ".join(capsys.readouterr().out.split())


def test_the_help_says_each_declared_default(capsys):
    for command in ("sweep", "optimize"):
        text = _help(command, capsys)
        for declared in declared_params(RunSettings):
            if declared.key in ("device",):
                continue
            unit = f" {declared.unit}" if declared.unit else ""
            assert f"({declared.path}; default {declared.default_text()}{unit})" in text
    paper = _help("paper", capsys)
    assert '(run.workers; default "auto")' in paper
