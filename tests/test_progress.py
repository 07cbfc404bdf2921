"""Progress: a bar on a terminal, one final line in a log (stderr not a terminal)."""

from __future__ import annotations

import io
import os
import re
import subprocess
import sys

import pytest

from glshade.progress import FinalLine, progress_bar


class Terminal(io.StringIO):
    """A stream that says it is a terminal."""

    def isatty(self) -> bool:
        return True


def test_a_terminal_gets_a_bar():
    stream = Terminal()
    bar = progress_bar(4, "glshade sweep", "case", stream=stream)
    assert not isinstance(bar, FinalLine)
    for _ in range(4):
        bar.update(1)
    bar.close()
    drawn = stream.getvalue()
    assert "\r" in drawn and "glshade sweep" in drawn and "4/4" in drawn
    # told it is a terminal, whatever the stream says
    told = io.StringIO()
    bar = progress_bar(2, "glshade paper", "case", stream=told, terminal=True)
    bar.update(2)
    bar.close()
    assert "\r" in told.getvalue()


def test_a_log_gets_one_final_line():
    log = io.StringIO()
    bar = progress_bar(126, "glshade sweep", "case", initial=26, stream=log)
    assert isinstance(bar, FinalLine)
    for _ in range(100):
        bar.update(1)
        assert log.getvalue() == ""  # nothing while it runs
    bar.close()
    bar.close()  # closing twice prints once
    lines = log.getvalue().splitlines()
    assert len(lines) == 1
    assert re.fullmatch(r"glshade sweep: 126/126 cases in \d+\.\d s \(100 this run\)", lines[0])


def test_a_log_gets_nothing_from_a_transient_or_unfinished_bar():
    log = io.StringIO()
    frame = progress_bar(1024, "glshade render", "row", initial=256, leave=False, stream=log)
    frame.update(768)
    frame.close()
    stopped = progress_bar(10, "glshade paper", "case", stream=log)
    stopped.update(3)
    stopped.close()  # an error or Ctrl-C: its own line says so
    assert log.getvalue() == ""
    assert progress_bar(10, "glshade paper", "case", enabled=False) is None  # --no-progress


def test_a_slow_frame_draws_no_bar_into_a_log(monkeypatch, capfd):
    import glshade.gpu.renderer as renderer_module
    from glshade.gpu.renderer import Renderer
    from glshade.scene import Scene

    monkeypatch.setattr(renderer_module, "PROGRESS_AFTER_SECONDS", 0.0)  # every frame is "slow"
    monkeypatch.setattr(renderer_module, "SINGLE_DRAW_WORK", 1)  # in many bands
    with Renderer(progress=True) as renderer:
        renderer.render(Scene().with_size(32), ("image",))
    assert capfd.readouterr().err == ""


def test_a_sweep_in_a_log_ends_with_one_progress_line(tmp_path):
    sweep = tmp_path / "s.toml"
    sweep.write_text('size = 32\n[grid]\n"camera.theta_deg" = [45, 30, 15]\n', encoding="utf-8")
    result = subprocess.run(
        [sys.executable, "-m", "glshade", "sweep", str(sweep), "--out", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        env={**os.environ, "COLUMNS": "80"},
        timeout=300,
    )
    assert result.returncode == 0, result.stderr
    assert "\r" not in result.stderr and "█" not in result.stderr and "|" not in result.stderr
    progress = [line for line in result.stderr.splitlines() if line.startswith("glshade sweep:")]
    assert len(progress) == 1, result.stderr
    assert re.fullmatch(r"glshade sweep: 3/3 cases in \d+(\.\d)? s", progress[0])


@pytest.mark.parametrize("flag", ["--no-progress"])
def test_no_progress_means_no_line(tmp_path, flag):
    sweep = tmp_path / "s.toml"
    sweep.write_text('size = 32\n[grid]\n"camera.theta_deg" = [45]\n', encoding="utf-8")
    result = subprocess.run(
        [sys.executable, "-m", "glshade", "sweep", str(sweep), "--out", str(tmp_path / "o"), flag],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr
    assert "glshade sweep:" not in result.stderr
