"""Hostile input, second pass: a careless or hostile user loses no file outside the output
directory and no input, hangs no command, and sees no traceback; stored results are
checked when read. Each test builds the trap, runs the real ``glshade`` command (a fresh
interpreter, like a user's shell) or the library, and checks what is left on disk."""

from __future__ import annotations

import csv
import io
import json
import math
import os
import signal
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest

from glshade.app.cli import main
from glshade.errors import GlshadeError
from glshade.files import (
    atomic_write_bytes,
    check_entries,
    check_inside,
    check_output,
    read_regular,
    reading_inputs,
)
from glshade.measure.case_files import case_file_bytes, read_case_file
from glshade.scene import Scene
from glshade_process import run_glshade

#: The paper's study reduced to one case at 64² (about 4 s on two cores).
ONE_CASE = [
    "paper",
    "--surfaces",
    "flat",
    "--thetas",
    "45",
    "--sigma2s",
    "4",
    "--dmaxs",
    "5um",
    "--size",
    "64",
    "--workers",
    "0",
    "--no-progress",
]
CASE = "flat_theta45_sigma2_4_dmax5um"


def glshade(*args: str, cwd: Path, timeout: float = 120):
    """``glshade ARGS`` as a user runs it; a hang fails the test (``timeout``)."""
    return run_glshade(*args, cwd=cwd, timeout=timeout)


def one_error(result: subprocess.CompletedProcess, *fragments: str) -> str:
    """The run's one line of error (exit 2, no traceback), which names ``fragments``."""
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2, result.stderr
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("glshade: error: ") and "Traceback" not in result.stderr
    for fragment in fragments:
        assert fragment in lines[0], lines[0]
    return lines[0]


def listing(root: Path) -> dict[str, tuple[int, int]]:
    """Every path under ``root`` (links not followed) with its size and mtime (a
    directory's: 0, 0)."""
    out = {}
    for path in sorted(root.rglob("*")):
        info = path.lstat()
        kept = (
            (0, 0) if path.is_dir() and not path.is_symlink() else (info.st_size, info.st_mtime_ns)
        )
        out[str(path.relative_to(root))] = kept
    return out


# --------------------------------------------------------------------------- outputs stay put
def _traps(root: Path) -> dict[str, list[str]]:
    """Directories and files laid as traps, and the command line that walks into each."""
    outside = root / "outside"
    outside.mkdir()
    (outside / "precious.md").write_text("the user's own notes\n")
    linked_cases = root / "linked_cases"
    linked_cases.mkdir()
    (linked_cases / "cases").symlink_to(outside)
    linked_report = root / "linked_report"
    linked_report.mkdir()
    (linked_report / "report.md").symlink_to(outside / "precious.md")
    fifo_lock = root / "fifo_lock"
    fifo_lock.mkdir()
    os.mkfifo(fifo_lock / ".glshade.lock.json")
    fifo_manifest = root / "fifo_manifest"
    fifo_manifest.mkdir()
    os.mkfifo(fifo_manifest / "study.json")
    fifo_case = root / "fifo_case"
    (fifo_case / "cases").mkdir(parents=True)
    os.mkfifo(fifo_case / "cases" / f"{CASE}.json")
    np.save(root / "heights.npy", np.zeros((16, 16)))
    (root / "map.toml").write_text(
        '# my panel\n[surface]\nkind = "heightmap"\nfile = "heights.npy"\nspacing = [1.0, 1.0]\n'
    )
    (root / "scene.toml").write_text("# my scene, with comments\n[camera]\ntheta_deg = 30.0\n")
    maps = root / "maps"
    maps.mkdir()
    np.save(maps / "decoded.npy", np.zeros((4, 4)))
    (root / "maps.toml").write_text(
        '[surface]\nkind = "heightmap"\nfile = "maps/decoded.npy"\nspacing = [1.0, 1.0]\n'
    )
    _input_traps(root)
    return {
        **_INPUT_TRAPS,
        "cases link": [*ONE_CASE, "--out", "linked_cases"],
        "report link": [*ONE_CASE, "--out", "linked_report"],
        "lock fifo": [*ONE_CASE, "--out", "fifo_lock"],
        "manifest fifo": [*ONE_CASE, "--out", "fifo_manifest"],
        "case fifo": [*ONE_CASE, "--out", "fifo_case"],
        "uv over the height map": [
            "render", "map.toml", "--size", "8", "-o", "out.png", "--uv", "heights.npy",
        ],
        "save-scene over the scene": [
            "render", "scene.toml", "--size", "8", "-o", "out.png", "--save-scene", "scene.toml",
        ],
        "save-scene under /proc": [
            "render", "--size", "8", "-o", "out.png", "--save-scene", "/proc/scene.toml",
        ],
        "maps over an input": [
            "measure", "maps.toml", "--method", "pmd", "--size", "8", "--maps", "maps",
        ],
        "same file twice": [
            "coding", "scene.toml", "--size", "8", "--coded-scene", "x.toml", "--save-scene",
            "x.toml",
        ],
    }  # fmt: skip


def _input_traps(root: Path) -> None:
    """Links inside output folders that lead to one of the run's inputs or to a sibling,
    and an output folder glshade cannot write in: each refused before any work."""
    (root / "maps_link").mkdir()
    (root / "maps_link" / "decoded.npy").symlink_to(root / "heights.npy")
    (root / "frames_link").mkdir()
    (root / "frames_link" / "manifest.json").symlink_to(root / "scene.toml")
    (root / "sweep.toml").write_text('size = 8\n[grid]\n"camera.theta_deg" = [30, 45]\n')
    (root / "sweep_link").mkdir()
    (root / "sweep_link" / "results.csv").symlink_to(root / "sweep.toml")
    sibling = root / "sibling"
    sibling.mkdir()
    (sibling / "notes.md").write_text("the user's notes, beside the study\n")
    (sibling / "report.md").symlink_to("notes.md")
    study = root / "pmd_out"
    study.mkdir()
    (study / "bowl.toml").write_text(
        '[surface]\nkind = "formula"\nexpression = "0.0005*x^2 + 0.0005*z^2"\n'
    )
    (study / "pmd_report.md").symlink_to("bowl.toml")
    cases = root / "case_sibling" / "cases"
    cases.mkdir(parents=True)
    (cases / "other.json").write_text("{}\n")
    (cases / f"{CASE}.json").symlink_to("other.json")


#: Commands that would write over one of their inputs, or into a place they cannot write.
_INPUT_TRAPS = {
    "maps link to the height map": [
        "measure", "map.toml", "--method", "pmd", "--size", "8", "--maps", "maps_link",
    ],
    "manifest link to the scene": [
        "measure", "scene.toml", "--method", "pmd", "--size", "8", "--frames", "frames_link",
    ],
    "maps under /proc": [
        "measure", "--method", "pmd", "--size", "8", "--frames", "fresh_frames", "--maps",
        "/proc/self/fd",
    ],
    "results link to the sweep file": ["sweep", "sweep.toml", "--out", "sweep_link"],
    "report link to a sibling": [*ONE_CASE, "--out", "sibling"],
    "pmd report link to a scene read": [
        *ONE_CASE[:2], "pmd_out/bowl.toml", *ONE_CASE[3:], "--method", "pmd", "--out", "pmd_out",
    ],
    "case link to a sibling": [*ONE_CASE, "--out", "case_sibling"],
}  # fmt: skip

#: What each trap's one line says.
TRAP_MESSAGES = {
    "maps link to the height map": ("--maps maps_link: decoded.npy is a symbolic link",),
    "manifest link to the scene": ("--frames frames_link: manifest.json is a symbolic link",),
    "maps under /proc": ("--maps /proc/self/fd: cannot write in /proc/self/fd",),
    "results link to the sweep file": ("results.csv is a link to", "outside the output"),
    "report link to a sibling": ("sibling/report.md is a symbolic link (to notes.md)",),
    "pmd report link to a scene read": ("pmd_report.md is a symbolic link (to bowl.toml)",),
    "case link to a sibling": (f"{CASE}.json is a symbolic link (to other.json)",),
    "cases link": ("linked_cases/cases is a link to", "outside the output directory"),
    "report link": ("report.md is a link to", "outside the output directory"),
    "lock fifo": (".glshade.lock.json is a FIFO",),
    "manifest fifo": ("study.json is a FIFO",),
    "case fifo": (f"{CASE}.json is a FIFO",),
    "uv over the height map": ("--uv heights.npy: is one of this run's inputs",),
    "save-scene over the scene": ("--save-scene scene.toml: is one of this run's inputs",),
    "save-scene under /proc": ("--save-scene /proc/scene.toml: ",),
    "maps over an input": ("--maps maps/decoded.npy: is one of this run's inputs",),
    "same file twice": ("is also --coded-scene's output",),
}


@pytest.fixture(scope="module")
def trapped(tmp_path_factory):
    root = tmp_path_factory.mktemp("traps")
    commands = _traps(root)
    before = listing(root)
    with ThreadPoolExecutor(max_workers=2) as pool:
        results = dict(
            zip(
                commands,
                pool.map(lambda a: glshade(*a, cwd=root, timeout=60), commands.values()),
                strict=True,
            )
        )
    return root, results, before


@pytest.mark.slow
@pytest.mark.parametrize("trap", list(TRAP_MESSAGES))
def test_a_trap_is_one_line_before_any_work(trapped, trap):
    _, results, _ = trapped
    one_error(results[trap], *TRAP_MESSAGES[trap])


@pytest.mark.slow
def test_the_traps_leave_every_file_as_it_was(trapped):
    """Nothing outside the output directory, no input, no special file is touched, and
    the refused runs create nothing: the tree is the same, file for file, size for size
    and mtime for mtime."""
    root, _, before = trapped
    assert listing(root) == before
    assert (root / "outside" / "precious.md").read_text() == "the user's own notes\n"
    assert (root / "scene.toml").read_text().startswith("# my scene, with comments")
    assert not (root / "out.png").exists()


def test_check_inside_follows_every_link(tmp_path):
    out = tmp_path / "out"
    (out / "sub").mkdir(parents=True)
    (tmp_path / "elsewhere").mkdir()
    (out / "away").symlink_to(tmp_path / "elsewhere")
    (out / "here").symlink_to(out / "sub")
    assert check_inside(out, out / "here" / "x.json", "--out") == out / "sub" / "x.json"
    with pytest.raises(GlshadeError, match="away is a link to .*elsewhere, outside the output"):
        check_inside(out, out / "away" / "x.json", "--out")
    with pytest.raises(GlshadeError, match="away is a link"):
        check_entries(out)


def test_an_unwritable_directory_is_found_by_a_probe(tmp_path):
    """``os.access`` answers yes for root under /proc; the probe creates a file."""
    if os.access("/proc", os.W_OK):  # root: permission bits say yes, the probe says no
        with pytest.raises(GlshadeError, match=r"cannot write in /proc \("):
            check_output("/proc/x.toml", "--save-scene")
    assert check_output(tmp_path / "x.toml", "--save-scene") == tmp_path / "x.toml"
    assert list(tmp_path.iterdir()) == []  # the probe is gone


@pytest.mark.parametrize("kind", ["fifo", "dir", "missing"])
def test_reading_a_special_file_never_blocks(tmp_path, kind):
    path = tmp_path / "study.json"
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "dir":
        path.mkdir()
    words = {"fifo": "is a FIFO", "dir": "is a directory", "missing": "does not exist"}[kind]
    start = time.monotonic()
    with pytest.raises(GlshadeError, match=words):
        read_regular(path, "--out")
    assert time.monotonic() - start < 5


def test_a_fifo_scene_file_is_refused_without_waiting(tmp_path):
    os.mkfifo(tmp_path / "scene.toml")
    result = glshade("render", "scene.toml", "-o", "x.png", cwd=tmp_path, timeout=30)
    one_error(result, "scene.toml", "is a FIFO")


# --------------------------------------------------------------------------- stored results
def test_a_case_file_vouches_for_itself(tmp_path):
    path = tmp_path / "a.json"
    path.write_bytes(case_file_bytes("a", {"visibility_px": 3.0, "status": "ok"}))
    assert read_case_file(path, "a").record == {"visibility_px": 3.0, "status": "ok"}
    assert read_case_file(path, "b").problem == "holds case 'a', not 'b'"
    data = json.loads(path.read_text())
    data["visibility_px"] = 1e308
    path.write_text(json.dumps(data))
    assert read_case_file(path, "a").problem == "fails its checksum (edited or damaged)"
    del data["checksum"]
    path.write_text(json.dumps(data))
    assert "has no checksum" in str(read_case_file(path, "a").problem)
    path.write_text("[" * 100_000)
    assert read_case_file(path, "a").problem == "is not JSON written by glshade"
    absent = read_case_file(tmp_path / "none.json", "a")
    assert absent.record is None and absent.problem is None  # simply not measured yet


def measured(study: Path) -> dict[str, str]:
    """The one row of a study's ``results.csv``, its timings left out."""
    from glshade.study.store import COLUMNS

    timings = {c.name for c in COLUMNS if c.role == "timing"}
    rows = list(csv.DictReader(io.StringIO((study / "results.csv").read_text())))
    assert len(rows) == 1
    return {name: value for name, value in rows[0].items() if name not in timings}


@pytest.mark.slow
def test_a_tampered_study_case_is_measured_again_and_said(tmp_path):
    first = glshade(*ONE_CASE, "--out", "study", cwd=tmp_path)
    assert first.returncode == 0, first.stderr
    table = measured(tmp_path / "study")
    assert table["visibility_px"] == "0.0"
    case = tmp_path / "study" / "cases" / f"{CASE}.json"
    data = json.loads(case.read_text())
    data["visibility_px"] = 1e308
    case.write_text(json.dumps(data))
    again = glshade(*ONE_CASE, "--out", "study", cwd=tmp_path)
    assert again.returncode == 0, again.stderr
    warning = [line for line in again.stderr.splitlines() if "could not be trusted" in line]
    assert warning == [
        "glshade: warning: 1 case file could not be trusted and is measured again: "
        f"{CASE}.json fails its checksum (edited or damaged)"
    ]
    assert "1 cases computed, 0 resumed" in again.stdout
    assert measured(tmp_path / "study") == table

    # one who recomputes the checksum still cannot put text where a number belongs
    data = json.loads(case.read_text())
    data.pop("checksum")
    data["visibility_px"] = "3 px"
    case.write_bytes(case_file_bytes(data.pop("case_id"), data))
    third = glshade(*ONE_CASE, "--out", "study", cwd=tmp_path)
    assert third.returncode == 0, third.stderr
    assert f"{CASE}.json holds str as visibility_px, not float" in third.stderr
    assert measured(tmp_path / "study") == table


# --------------------------------------------------------------------------- one line, always
def test_an_unforeseen_exception_is_one_line_and_exit_1(monkeypatch, capsys):
    from glshade.app.commands import info

    def broken(args):
        raise ValueError("an array of shape (0,)\nsecond line")

    monkeypatch.setattr(info, "run", broken)
    assert main(["info"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith("glshade: internal error: ValueError: an array of shape (0,) second line")
    assert "please report it" in err and "--verbose" in err
    assert main(["info", "--verbose"]) == 1
    assert "Traceback" in capsys.readouterr().err


def test_ctrl_c_in_a_command_is_one_line_and_130(monkeypatch, capsys):
    from glshade.app.commands import info

    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(info, "run", interrupted)
    assert main(["info"]) == 130
    assert capsys.readouterr().err == "glshade: interrupted\n"


def test_a_warning_is_one_line(monkeypatch, capsys):
    import warnings

    from glshade.app.commands import info

    def warns(args):
        warnings.warn("overflow encountered in multiply", RuntimeWarning, stacklevel=1)
        warnings.warn("overflow encountered in multiply", RuntimeWarning, stacklevel=1)
        return 0

    monkeypatch.setattr(info, "run", warns)
    assert main(["info"]) == 0
    assert capsys.readouterr().err == (
        "glshade: warning: RuntimeWarning: overflow encountered in multiply\n"
    )


@pytest.mark.parametrize("delay_s", [0.02, 0.06, 0.15, 0.4, 0.8])
def test_ctrl_c_during_start_up_is_one_line(tmp_path, delay_s):
    """SIGINT ``delay_s`` after glshade's entry point started (its first line runs before
    glshade imports anything: NumPy, the scene, moderngl follow): exit 130 and one line,
    never a traceback. (Python's own start-up before that line is outside glshade's
    reach; ``PYTHONPROFILEIMPORTTIME`` tells when the entry point is reached.)

    The status is 130, or death by SIGINT, which a shell also reports as 130: CPython ends
    a process that way when the interrupt passed through code it ran by ``PyRun_String``,
    even though glshade caught it, and after the command finished SIGINT's own default
    action ends the exit silently."""
    process = subprocess.Popen(
        [sys.executable, "-m", "glshade", "measure", "--size", "32"],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPROFILEIMPORTTIME": "1"},
    )
    assert process.stderr is not None
    for line in process.stderr:
        if line.rstrip().endswith("glshade.app.entry"):
            break
    time.sleep(delay_s)
    process.send_signal(signal.SIGINT)
    out, rest = process.communicate(timeout=60)
    said = [line for line in rest.splitlines() if not line.startswith("import time:")]
    assert "Traceback" not in rest, rest
    if process.returncode == 0 or not said:  # it finished first (and exited, maybe killed)
        assert process.returncode in (0, -signal.SIGINT) and "visibility_px" in out, rest
        return
    assert process.returncode in (130, -signal.SIGINT), rest
    assert said == ["glshade: interrupted"], said


# --------------------------------------------------------------------------- values
@pytest.mark.parametrize(
    "text, fragment",
    [
        ("a = " + "[" * 3000 + "]" * 3000 + "\n", "nested at most a few hundred levels"),
        ("[camera]\ntheta_deg = 1" + "0" * 400 + "\n", "got an integer of 401 digits"),
        ("[camera]\ntheta_deg = 1" + "0" * 5000 + "\n", "an integer of thousands of digits"),
        ("[camera]\ntheta_deg = 5e-324\n", "camera.theta_deg: must be in (0.001, 90) degrees"),
        ("[defect]\ndmax = 1e400\n", "defect.dmax: must be a finite number, got inf"),
    ],
    ids=["nesting", "long integer", "huge integer", "denormal theta", "infinite depth"],
)
def test_extreme_numbers_are_one_line(tmp_path, capsys, text, fragment):
    (tmp_path / "s.toml").write_text(text)
    assert main(["render", str(tmp_path / "s.toml"), "-o", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and fragment in err, err
    assert not (tmp_path / "x.png").exists()


def test_a_far_phase_shows_the_same_stripes(renderer):
    """The stripes repeat every period: a phase of -9.2e18 mm is reduced exactly before
    float32 sees it (it used to render blank white)."""
    period = 2.0
    far = -9.2e18
    near = math.remainder(far, period)
    base = Scene().with_size(48)
    images = [
        renderer.render(base.updated(emitter={"phase": phase}), ("image",)).output("image")
        for phase in (far, near)
    ]
    assert np.array_equal(images[0], images[1])
    assert 0.2 < float(np.mean(images[0])) < 0.8  # stripes, not a blank image


def test_measuring_a_one_pixel_image_is_one_line(capsys):
    assert main(["measure", "--size", "1"]) == 2
    err = capsys.readouterr().err
    assert err == (
        "glshade: error: --size / camera.width, camera.height: the paper's metric needs at "
        "least 2 pixels each way, got 1x1\n"
    )


# ------------------------------------------------------------------- never over an input
def test_a_file_the_run_read_is_never_written(tmp_path):
    """Inside a run's record of its inputs, a file a reader opened is refused as an
    output however it is named: its path, a link to it, a hard link to it; outside the
    run it is an ordinary file again."""
    scene = tmp_path / "scene.toml"
    scene.write_text("[camera]\ntheta_deg = 30.0\n")
    (tmp_path / "link.toml").symlink_to(scene)
    os.link(scene, tmp_path / "hard.toml")
    with reading_inputs():
        Scene.load(scene)
        for name in ("scene.toml", "link.toml", "hard.toml"):
            with pytest.raises(GlshadeError, match=r"is one of this run's inputs \(.*scene"):
                atomic_write_bytes(tmp_path / name, b"x", "-o")
            with pytest.raises(GlshadeError, match="is one of this run's inputs"):
                check_output(tmp_path / name, "-o")
        atomic_write_bytes(tmp_path / "other.toml", b"x", "-o")
    assert scene.read_text() == "[camera]\ntheta_deg = 30.0\n"
    atomic_write_bytes(tmp_path / "hard.toml", b"x", "-o")  # the run is over


def test_a_named_output_is_never_written_through_a_link(tmp_path):
    """A file glshade names inside its output folder is its own: a link there (to a
    sibling, to a file elsewhere) is refused, and the file it leads to keeps its bytes."""
    (tmp_path / "notes.md").write_text("mine\n")
    (tmp_path / "report.md").symlink_to("notes.md")
    with pytest.raises(GlshadeError, match=r"report.md is a symbolic link \(to notes.md\)"):
        atomic_write_bytes(tmp_path / "report.md", b"x", within=tmp_path)
    with pytest.raises(GlshadeError, match="report.md is a symbolic link"):
        check_entries(tmp_path)
    assert (tmp_path / "notes.md").read_text() == "mine\n"


def test_the_viewer_saves_neither_over_its_scene_nor_through_a_link(tmp_path):
    """T over the scene the viewer opened (``glshade_view.toml`` itself) and T or S
    through a link: refused in the panel's message line; the files are as they were."""
    from types import SimpleNamespace

    from glshade.app.viewer.window import ViewerWindow

    opened = tmp_path / "glshade_view.toml"
    opened.write_text("[camera]\ntheta_deg = 20.0\n")
    shots: list[Path] = []
    window = SimpleNamespace(
        model=SimpleNamespace(scene=Scene.load(opened)),
        stats={"frames": 7},
        status={},
        screenshot=lambda path, redraw: shots.append(path),
    )
    with reading_inputs():
        Scene.load(opened)
        ViewerWindow._save(window, False, tmp_path)
        assert "is one of this run's inputs" in window.status["message"]
    assert opened.read_text() == "[camera]\ntheta_deg = 20.0\n"
    elsewhere = tmp_path / "elsewhere.png"
    (tmp_path / "glshade_view_7.png").symlink_to(elsewhere)
    ViewerWindow._save(window, True, tmp_path)
    assert "glshade_view_7.png is a symbolic link" in window.status["message"]
    assert not shots and not elsewhere.exists()
    opened.unlink()
    ViewerWindow._save(window, False, tmp_path)  # no input in the way: written
    assert (
        window.status["message"] == f"wrote {opened}" and "theta_deg = 20.0" in opened.read_text()
    )
