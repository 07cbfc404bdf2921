"""The snapshot plugin against hostile baselines and folders: every error is one line (a
failed test, or a usage error), never a traceback.

- a sidecar nested 100 000 deep (a RecursionError once), numbers that are not tables (an
  AttributeError once), fields of the wrong type, out of range or with line breaks;
- a PNG that declares 16384² 16-bit samples in 0.5 MB: refused from its header, before a
  sample is decoded;
- ``--glshade-results`` whose ``index.html`` is a link out of it or a FIFO (a 65-line
  traceback once), also when it turns into one during the run;
- a baseline folder linked out of the project under ``--glshade-update``;
- two tests of one snapshot name on two pytest-xdist workers: each worker a process of
  its own, simulated (pytest-xdist need not be installed) with the ``workerinput`` and
  the ``pytest_configure_node`` hook the real controller and workers use.

The unit tests read baselines written by :class:`glshade.snapshot.baseline.Baseline`;
the plugin's tests follow ``test_snapshot_plugin.py`` (pytester, 64² scenes).
"""

from __future__ import annotations

import json
import os
import re
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

from glshade.errors import GlshadeError
from glshade.snapshot import baseline as stored
from glshade.snapshot import claims
from test_snapshot_plugin import (  # noqa: F401 - the warm-up fixture, for pytester
    SCENE,
    _imported_here_first,
    baseline_dir,
    updated,
    user_test,
)

pytest_plugins = ["pytester"]

NUMBERS = {"paper": {"visibility_px": 2.0, "deflection_px": 1.1451, "status": "ok"}}
SCENE_TABLES = {"camera": {"theta_deg": 30.0, "distortion": [0.0, 0.0]}, "defect": {"dmax": 0.004}}


def write_baseline(folder: Path, numbers=NUMBERS, renderer: str = "llvmpipe") -> Path:
    """A 40x48 baseline ``panel`` written by glshade; returns its sidecar's path."""
    rows = np.arange(48)[:, None] + 0.1 * np.arange(40)[None, :]
    image = 0.5 + 0.5 * np.cos(rows / 3.0)
    stored.Baseline("panel", image, numbers, SCENE_TABLES, renderer, "fp32", "0.1.0").write(folder)
    return folder / "panel.json"


def edited(side: Path, change) -> None:
    """The sidecar rewritten with ``change(data)`` applied (``json.dumps`` writes NaN)."""
    data = json.loads(side.read_text())
    change(data)
    side.write_text(json.dumps(data))


def deep(levels: int) -> str:
    return "[" * levels + "]" * levels


def nested_scene(side: Path, levels: int) -> None:
    """The sidecar with a list ``levels`` deep under ``scene.camera``."""
    edited(side, lambda d: d["scene"]["camera"].update(deep=None))
    text = side.read_text().replace('"deep": null', f'"deep": {deep(levels)}')
    side.write_text(text)


def one_line(caught: pytest.ExceptionInfo) -> str:
    text = str(caught.value)
    assert "\n" not in text and text.strip() == text
    return text


# --------------------------------------------------------------------------- sidecars
def test_a_sidecar_nested_too_deep_is_one_line_before_it_is_parsed(tmp_path):
    side = write_baseline(tmp_path)
    nested_scene(side, 100_000)
    with pytest.raises(GlshadeError) as caught:
        stored.read(tmp_path, "panel")
    assert one_line(caught) == (
        f"snapshot sidecar {side}: nested more than 16 levels deep; not a sidecar glshade writes"
    )
    # sixteen levels in all (the sidecar, the scene, its camera, 13 lists) still read
    side = write_baseline(tmp_path)
    nested_scene(side, 13)
    assert stored.read(tmp_path, "panel").scene["camera"]["deep"] == json.loads(deep(13))
    nested_scene(side, 14)
    with pytest.raises(GlshadeError, match="nested more than 16 levels deep"):
        stored.read(tmp_path, "panel")


def test_nesting_is_counted_outside_strings():
    assert stored.nesting('{"a": "[[[[[[[[[[[[[[[[[[[[", "b": [[1]]}') == 3
    assert stored.nesting('{"a": "\\"[[[[[[[[[[[[[[[[[[[[\\""}') == 1
    assert stored.nesting(deep(100_000)) == 17  # stops counting past the limit


@pytest.mark.parametrize(
    ("change", "needle"),
    [
        (lambda d: d.update(numbers={"paper": [1, 2]}),
         "numbers.paper must be the table of an instrument's numbers (paper, pmd)"),
        (lambda d: d.update(numbers={"sensor": {}}),
         "numbers.sensor must be the table of an instrument's numbers (paper, pmd)"),
        (lambda d: d["numbers"]["paper"].update(visibility_px="3 px"),
         "numbers.paper holds str as visibility_px, not float"),
        (lambda d: d["numbers"]["paper"].update(visibility_px=10**400),
         "numbers.paper holds 1000000000000000000000000000000000000... as visibility_px, "
         "outside 0 to 1e+06"),
        (lambda d: d["numbers"]["paper"].update(deflection_px=float("nan")),
         "numbers.paper holds nan as deflection_px, not a finite number"),
        (lambda d: d["numbers"]["paper"].update(status="bogus"),
         "numbers.paper holds 'bogus' as status, not one of ok, outside, edge"),
        (lambda d: d["numbers"]["paper"].update(status_reason="a\n<b>b</b>"),
         "holds the control character U+000A in numbers.paper.status_reason"),
        (lambda d: d["numbers"]["paper"].update(extra={"a": 1}),
         "numbers.paper holds a dict as extra, not a number"),
        (lambda d: d.update(renderer="llvm\rpipe"),
         "holds the control character U+000D in renderer"),
        (lambda d: d["scene"].update(camera=3), "scene.camera must be a table of keys"),
        (lambda d: d["scene"]["camera"].update({"\x1b[2J": 1}),
         "holds the control character U+001B in scene.camera"),
        (lambda d: d["image"].update(width=16384, height=16384),
         "image of 16384x16384 pixels, more than a baseline holds (16777216: 4096x4096)"),
        (lambda d: d["image"].update(scale=float("inf")), "image scale must be a positive number"),
        (lambda d: d["image"].update(width=True), "image width/height must be whole numbers"),
    ],
    ids=["numbers-list", "unknown-instrument", "text-number", "huge-int", "nan", "status",
         "reason-line-break", "nested-number", "renderer-line-break", "scene-table",
         "scene-key-escape", "image-too-big", "scale-inf", "width-bool"],
)  # fmt: skip
def test_a_sidecar_field_of_the_wrong_kind_is_one_line(tmp_path, change, needle):
    side = write_baseline(tmp_path)
    edited(side, change)
    with pytest.raises(GlshadeError) as caught:
        stored.read(tmp_path, "panel")
    text = one_line(caught)
    assert text.startswith(f"snapshot sidecar {side}: ") and needle in text, text


def test_unknown_numbers_beside_the_records_are_kept(tmp_path):
    """A key that is no column of the record (an older glshade's) is shown, not compared:
    any one value reads back."""
    numbers = {"paper": {**NUMBERS["paper"], "old_column": 3.5, "old_word": "kept"}}
    write_baseline(tmp_path, numbers)
    assert stored.read(tmp_path, "panel").numbers == numbers


def test_a_pmd_station_s_numbers_are_checked_by_its_record(tmp_path):
    numbers = {**NUMBERS, "pmd": {"pmd_shift_mm": 0.7, "unwrap_failures": 0, "status": "edge"}}
    side = write_baseline(tmp_path, numbers)
    assert stored.read(tmp_path, "panel").numbers == numbers
    edited(side, lambda d: d["numbers"]["pmd"].update(unwrap_failures=2**63))
    with pytest.raises(GlshadeError, match=r"numbers.pmd holds 9223372036854775808 as unwrap"):
        stored.read(tmp_path, "panel")


# --------------------------------------------------------------------------- images
def png_of(width: int, height: int, bits: int = 16, colour: int = 0) -> bytes:
    """A PNG declaring ``width`` x ``height``: its IHDR right, one row of data."""

    def chunk(kind: bytes, body: bytes) -> bytes:
        return (
            struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))
        )

    header = struct.pack(">IIBBBBB", width, height, bits, colour, 0, 0, 0)
    rows = zlib.compress(b"\x00" * (1 + width * bits // 8))
    return (
        b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", rows) + chunk(b"IEND", b"")
    )


@pytest.fixture
def no_decoding(monkeypatch):
    """OpenCV's decoder, made to fail the test if it is reached."""
    import cv2

    def refuse(*args, **kwargs):
        raise AssertionError("a PNG was decoded")

    monkeypatch.setattr(cv2, "imdecode", refuse)


def test_a_decompression_bomb_is_refused_from_its_header(tmp_path, no_decoding):
    """A 16384² 16-bit PNG (0.5 MB, 512 MiB decoded, 2.7 GB as floats) whose sidecar
    says 4096² is refused before a sample is decoded; so is one whose sidecar agrees."""
    side = write_baseline(tmp_path)
    (tmp_path / "panel.png").write_bytes(png_of(16384, 16384))
    edited(side, lambda d: d["image"].update(width=4096, height=4096))
    with pytest.raises(GlshadeError) as caught:
        stored.read(tmp_path, "panel")
    assert one_line(caught) == (
        f"snapshot image {tmp_path / 'panel.png'}: declares 16384 x 16384 pixels, 16-bit, "
        "1 channel = 268435456 pixels, more than the 16777216 allowed (a baseline holds at "
        "most 4096x4096); nothing was decoded"
    )
    (tmp_path / "panel.png").write_bytes(png_of(4096, 4096, colour=2))
    with pytest.raises(GlshadeError, match=r"not a 16-bit greyscale PNG \(4096 x 4096 pixels"):
        stored.read(tmp_path, "panel")
    (tmp_path / "panel.png").write_bytes(png_of(4096, 4000))
    with pytest.raises(GlshadeError, match=r"panel.png: is 4096x4000, its sidecar says 4096x4096"):
        stored.read(tmp_path, "panel")


def test_a_baseline_larger_than_it_can_be_read_is_not_written(tmp_path):
    image = np.zeros((4096, 4097))
    with pytest.raises(GlshadeError) as caught:
        stored.Baseline("big", image, NUMBERS, SCENE_TABLES, "r", "fp32", "0").write(tmp_path)
    assert "the image is 4097x4096 pixels, more than a baseline holds" in one_line(caught)
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------- claims
def test_a_name_is_claimed_by_one_test_across_processes(tmp_path):
    assert claims.claim(tmp_path, "same", "a.py::t") is None
    assert claims.claim(tmp_path, "same", "a.py::t") is None  # the same test again
    assert claims.collided(tmp_path, "same") == []
    assert claims.claim(tmp_path, "same", "b.py::u") == "a.py::t"
    assert claims.claim(tmp_path, "other", "b.py::u") is None
    assert claims.collided(tmp_path, "same") == ["a.py::t", "b.py::u"]
    assert claims.collisions(tmp_path) == {"same": ["a.py::t", "b.py::u"]}
    assert sorted(p.name for p in tmp_path.iterdir() if ".collision." not in p.name) == [
        "other",
        "same",
    ]  # no draft left behind


# --------------------------------------------------------------------------- the plugin
def failure_text(result: pytest.RunResult) -> list[str]:
    """The lines pytest prints for the one failed test (under its ``___ name ___``)."""
    lines = result.outlines
    start = next(i for i, line in enumerate(lines) if re.fullmatch(r"_+ test_\w+ _+", line))
    end = next(i for i in range(start + 1, len(lines)) if lines[i].startswith(("=", "_")))
    return [line for line in lines[start + 1 : end] if line.strip()]


def test_a_deep_sidecar_fails_the_test_in_one_line(pytester):
    user_test(pytester)
    updated(pytester)
    nested_scene(baseline_dir(pytester) / "panel.json", 100_000)
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)
    assert failure_text(result) == [
        f"glshade snapshot: snapshot sidecar {baseline_dir(pytester) / 'panel.json'}: nested "
        "more than 16 levels deep; not a sidecar glshade writes"
    ]
    assert "RecursionError" not in result.stdout.str()


def test_numbers_that_are_not_tables_fail_the_test_in_one_line(pytester):
    user_test(pytester)
    updated(pytester)
    edited(baseline_dir(pytester) / "panel.json", lambda d: d.update(numbers={"paper": [1]}))
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)
    (line,) = failure_text(result)
    assert line.endswith("numbers.paper must be the table of an instrument's numbers (paper, pmd)")
    assert "AttributeError" not in result.stdout.str()


def test_a_bomb_baseline_fails_the_test_in_one_line(pytester):
    user_test(pytester)
    updated(pytester)
    (baseline_dir(pytester) / "panel.png").write_bytes(png_of(32768, 32768))
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)
    (line,) = failure_text(result)
    assert "declares 32768 x 32768 pixels" in line and "nothing was decoded" in line


@pytest.mark.parametrize("kind", ["link-out", "fifo", "images-link-out"])
def test_a_results_folder_that_leads_elsewhere_is_a_usage_error(pytester, tmp_path, kind):
    user_test(pytester)
    out = pytester.path / "out"
    out.mkdir()
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    if kind == "link-out":
        (out / "index.html").symlink_to(outside / "index.html")
        needle = f"out/index.html is a link to {outside / 'index.html'}, outside the output"
    elif kind == "fifo":
        os.mkfifo(out / "index.html")
        needle = "out/index.html is a FIFO; glshade writes only regular files there"
    else:
        (out / "images").symlink_to(outside)
        needle = f"out/images is a link to {outside}, outside the output directory"
    result = pytester.runpytest("--glshade-results", "out")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    errors = [line for line in result.errlines if line.strip()]
    assert len(errors) == 1 and errors[0].startswith("ERROR: --glshade-results ")
    assert needle in errors[0]
    assert list(outside.iterdir()) == []


FIFO_DURING_THE_RUN = """
import os
from glshade.scene import paper_scene


def test_panel(glshade_snapshot):
    os.makedirs("out", exist_ok=True)
    os.mkfifo("out/index.html")  # what another process could do meanwhile
    glshade_snapshot.check({scene}, name="panel")
"""


def test_a_results_page_that_turns_into_a_fifo_is_one_line_at_the_end(pytester):
    pytester.makeini("[pytest]\n")
    pytester.makepyfile(test_user=FIFO_DURING_THE_RUN.format(scene=SCENE))
    result = pytester.runpytest("--glshade-results", "out")  # no baseline: a failure to show
    result.assert_outcomes(failed=1)
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    out = result.stdout.str()
    assert "INTERNALERROR" not in out and "Traceback" not in out
    result.stdout.fnmatch_lines(
        [
            "failed: no HTML summary: --glshade-results *out/index.html: is a FIFO; glshade "
            "only writes regular files"
        ]
    )
    assert "summary: " not in out.replace("no HTML summary", "")


def test_a_baseline_folder_linked_out_of_the_project_is_refused(pytester, tmp_path):
    user_test(pytester)
    outside = tmp_path / "shared_snaps"
    outside.mkdir()
    (pytester.path / "tests").mkdir()
    baseline_dir(pytester).symlink_to(outside)
    result = pytester.runpytest("--glshade-update")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    errors = [line for line in result.errlines if line.strip()]
    assert errors == [
        f"ERROR: glshade_snapshot_dir tests/glshade_snapshots: resolves to {outside}, outside "
        f"the project {pytester.path}; --glshade-update writes baselines only inside it (a "
        "folder linked elsewhere is refused): make it a folder of the project"
    ]
    assert list(outside.iterdir()) == []


# --------------------------------------------------------------------------- pytest-xdist
#: What pytest-xdist gives a worker and the controller, simulated: a worker's
#: ``config.workerinput`` (from FAKE_XDIST_WORKER), the controller's ``-n 2`` and its
#: ``pytest_configure_node`` call per worker, each worker a process of its own.
XDIST = """
import json
import os
import subprocess
import sys
import types

import pytest


@pytest.hookimpl(tryfirst=True)
def pytest_configure(config):
    if os.environ.get("FAKE_XDIST_WORKER"):
        config.workerinput = json.loads(os.environ["FAKE_XDIST_WORKER"])
    if os.environ.get("FAKE_XDIST_CONTROLLER"):
        config.option.numprocesses = 2
        config.option.dist = "load"


def pytest_sessionstart(session):
    if not os.environ.get("FAKE_XDIST_CONTROLLER"):
        return
    from glshade.snapshot import plugin

    config, workers = session.config, []
    for index, test in enumerate(("test_a.py", "test_b.py")):
        node = types.SimpleNamespace(config=config, workerinput={"workerid": f"gw{index}"})
        plugin.pytest_configure_node(node)
        env = {k: v for k, v in os.environ.items() if k != "FAKE_XDIST_CONTROLLER"}
        env["FAKE_XDIST_WORKER"] = json.dumps(node.workerinput)
        (config.rootpath / "claims.txt").write_text(node.workerinput["glshade_snapshot_claims"])
        argv = [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "--glshade-update", test]
        workers.append(subprocess.Popen(argv, env=env, cwd=config.rootpath, text=True,
                                        stdout=subprocess.PIPE, stderr=subprocess.STDOUT))
    for index, worker in enumerate(workers):
        (config.rootpath / f"gw{index}.log").write_text(worker.communicate(timeout=300)[0])
"""
TEST_A = f"""
from glshade.scene import paper_scene


def test_one(glshade_snapshot):
    glshade_snapshot.check({SCENE}, name="same")
"""
TEST_B = TEST_A.replace("test_one", "test_two").replace("30.0", "40.0")
COLLISION = (
    "snapshot name 'same' is checked by test_a.py::test_one and by test_b.py::test_two, on "
    "two pytest-xdist workers of one run; give each check its own name"
)
#: The same, in either order (two workers at once: either may claim first).
EITHER = re.compile(
    r"snapshot name 'same' is checked by (test_a\.py::test_one|test_b\.py::test_two) and by "
    r"(?!\1)(test_a\.py::test_one|test_b\.py::test_two), on two pytest-xdist workers of one "
    r"run; give each check its own name"
)


def xdist_project(pytester: pytest.Pytester) -> None:
    pytester.makeini("[pytest]\n")
    pytester.makeconftest(XDIST)
    pytester.makepyfile(test_a=TEST_A, test_b=TEST_B)


def as_worker(monkeypatch, index: int, folder: Path) -> None:
    inputs = {"workerid": f"gw{index}", claims.CLAIMS_KEY: str(folder)}
    monkeypatch.setenv("FAKE_XDIST_WORKER", json.dumps(inputs))


def test_two_workers_checking_one_name_fail_in_one_line(pytester, monkeypatch, tmp_path):
    """Worker gw0 checks 'same' first and writes it; gw1's test of the same name fails in
    one line naming the baseline and both tests, and writes nothing."""
    xdist_project(pytester)
    as_worker(monkeypatch, 0, tmp_path)
    pytester.runpytest("--glshade-update", "test_a.py").assert_outcomes(passed=1)
    written = (baseline_dir(pytester) / "same.json").read_bytes()
    as_worker(monkeypatch, 1, tmp_path)
    result = pytester.runpytest("--glshade-update", "test_b.py")
    result.assert_outcomes(failed=1)
    assert failure_text(result) == [f"glshade snapshot: {COLLISION}"]
    assert (baseline_dir(pytester) / "same.json").read_bytes() == written
    assert claims.collisions(tmp_path) == {"same": ["test_a.py::test_one", "test_b.py::test_two"]}


def test_the_controller_fails_the_run_naming_both_tests(pytester, monkeypatch):
    """The controller (``-n 2``) hands its claims folder to two worker processes that run
    at once; whichever checks 'same' second fails at once (the first too, if still
    running), and the controller fails the run with the one line, its folder removed."""
    xdist_project(pytester)
    monkeypatch.setenv("FAKE_XDIST_CONTROLLER", "1")
    result = pytester.runpytest("--glshade-update", "-k", "no_test_runs_here")
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    said = [line for line in result.outlines if line.startswith("failed: ")]
    assert len(said) == 1 and EITHER.fullmatch(said[0].removeprefix("failed: ")), said
    logs = [(pytester.path / f"gw{index}.log").read_text() for index in (0, 1)]
    failed = [log for log in logs if "1 failed" in log]
    assert failed and all(EITHER.search(log) for log in failed), logs
    assert all("Traceback" not in log and "Error" not in log for log in logs), logs
    assert not Path((pytester.path / "claims.txt").read_text()).exists()
