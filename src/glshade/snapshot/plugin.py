"""glshade's pytest plugin (entry point group ``pytest11``): snapshot tests of inspection
scenes.

    def test_my_panel(glshade_snapshot):
        scene = glshade.Scene.load("panel.toml")
        glshade_snapshot.check(scene, name="panel_theta30")

``check`` renders the scene, measures it (the paper's numbers; a phase-measuring
station's too where the scene shows fringes) and compares image and numbers with the
baseline stored under the folder the ini option ``glshade_snapshot_dir`` names (default
``tests/glshade_snapshots``, relative to the folder of ``pyproject.toml`` or
``pytest.ini``). Options: ``--glshade-update`` writes or rewrites baselines;
``--glshade-results DIR`` keeps the images of every failure and a one-page HTML summary;
``--glshade-fail-unused`` fails the run when a baseline was compared by no test;
``--glshade-renderer {auto,gl,oracle}`` picks the renderer. Tolerances: per call
(``check(..., image=2e-3)``), per test, class or file (``pytestmark =
pytest.mark.glshade_tolerance(visibility_px=0.05)``); ``docs/snapshot-testing.md``.

Loading the plugin imports neither OpenGL, OpenCV nor NumPy: a session that never asks
for the fixture pays nothing.

Every error is one line, never a traceback: a test's failure (a baseline that cannot be
read, :mod:`.baseline`; a name two tests check, across pytest-xdist's workers too,
:mod:`.claims`), a usage error at the start (a results folder whose ``index.html`` or
``images/`` is a link, a FIFO or leads out of it; a baseline folder that leads out of the
project under ``--glshade-update``), or a line of the summary at the end.
"""

from __future__ import annotations

import json
import os
import shlex
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

if TYPE_CHECKING:
    from glshade.instruments.table import MeasureTable
    from glshade.scene import Scene
    from glshade.snapshot.baseline import Baseline
    from glshade.snapshot.compare import Comparison
    from glshade.snapshot.report import Entry
    from glshade.snapshot.station import Shot, Station
    from glshade.snapshot.tolerance import Tolerances

#: The baseline folder where the ini file names none.
DEFAULT_DIR = "tests/glshade_snapshots"
MARKER = "glshade_tolerance"


def pytest_addoption(parser: pytest.Parser) -> None:
    group = parser.getgroup("glshade", "glshade snapshot tests")
    group.addoption(
        "--glshade-update",
        action="store_true",
        help="write or rewrite the baselines of every snapshot checked, instead of comparing",
    )
    group.addoption(
        "--glshade-results",
        metavar="DIR",
        help="keep actual, expected and difference images of every failure in DIR, and "
        "DIR/index.html: a one-page summary",
    )
    group.addoption(
        "--glshade-fail-unused",
        action="store_true",
        help="fail the run when a baseline in the snapshot folder was compared by no test",
    )
    group.addoption(
        "--glshade-renderer",
        choices=("auto", "gl", "oracle"),
        default="auto",
        help="auto: the OpenGL renderer, or the NumPy float64 oracle where no OpenGL context "
        "can be made; gl: OpenGL only; oracle: the oracle (default: auto)",
    )
    parser.addini(
        "glshade_snapshot_dir",
        f"folder of the glshade snapshot baselines (default: {DEFAULT_DIR})",
        default=DEFAULT_DIR,
    )


@dataclass
class SnapshotSession:
    """One pytest session's snapshot state: its options, what was checked and by whom."""

    directory: Path
    update: bool
    results: Path | None
    fail_unused: bool
    renderer: str
    checked: dict[str, str] = field(default_factory=dict)  # name -> test id
    entries: list[Entry] = field(default_factory=list)
    deselected: int = 0
    station: Station | None = None
    unused: list[str] = field(default_factory=list)
    #: Under pytest-xdist: the run's claims folder (:mod:`glshade.snapshot.claims`).
    claims: Path | None = None
    #: What the session's end could not do, one line each (said in its summary).
    problems: list[str] = field(default_factory=list)

    @classmethod
    def from_config(cls, config: pytest.Config) -> SnapshotSession:
        base = config.inipath.parent if config.inipath is not None else config.rootpath
        results = config.getoption("glshade_results")
        update = bool(config.getoption("glshade_update"))
        setting = str(config.getini("glshade_snapshot_dir"))
        directory = (base / setting).resolve()
        if update:
            _inside_project(directory, config.rootpath, setting)
        return cls(
            directory=directory,
            update=update,
            results=_results_folder(results) if results else None,
            fail_unused=bool(config.getoption("glshade_fail_unused")),
            renderer=str(config.getoption("glshade_renderer")),
            claims=_claims_folder(config),
        )


def _inside_project(directory: Path, root: Path, setting: str) -> None:
    """A usage error where the baseline folder, every link followed, leaves the project:
    ``--glshade-update`` writes baselines only inside it."""
    project = root.resolve()
    if directory != project and project not in directory.parents:
        raise pytest.UsageError(
            f"glshade_snapshot_dir {setting}: resolves to {directory}, outside the project "
            f"{project}; --glshade-update writes baselines only inside it (a folder linked "
            "elsewhere is refused): make it a folder of the project"
        )


def _results_folder(text: str) -> Path:
    """``--glshade-results``'s folder, or a usage error where something else is there, or
    where what the plugin writes there (``index.html``, ``images/``) is a link out of it,
    a link, a FIFO or another file that is not a regular one."""
    from glshade.errors import GlshadeError

    folder = Path(text).resolve()
    if folder.exists() and not folder.is_dir():
        raise pytest.UsageError(f"--glshade-results {text}: is not a directory")
    try:
        if folder.is_dir():
            _check_results(folder)
    except GlshadeError as exc:
        raise pytest.UsageError(str(exc)) from None
    return folder


def _check_results(folder: Path) -> None:
    from glshade.errors import GlshadeError
    from glshade.files import check_entries, check_inside, refuse_link, special_kind

    what, page, images = "--glshade-results", folder / "index.html", folder / "images"
    if os.path.lexists(page):
        check_inside(folder, page, what)
        refuse_link(folder, page, what)
        kind = special_kind(os.lstat(page).st_mode)
        if kind is not None:
            raise GlshadeError(
                f"{what} {folder}: {page} is {kind}; glshade writes only regular files there: "
                "remove it or choose another folder"
            )
    if os.path.lexists(images):
        check_inside(folder, images, what)
        if images.is_dir():
            check_entries(images, (), what)


def _claims_folder(config: pytest.Config) -> Path | None:
    """The run's claims folder under pytest-xdist: the controller makes it, each worker
    is given it (:func:`pytest_configure_node`); None in a single process."""
    from glshade.snapshot.claims import CLAIMS_KEY

    workerinput = getattr(config, "workerinput", None)
    if isinstance(workerinput, dict):
        given = workerinput.get(CLAIMS_KEY)
        return Path(given) if given else None
    if _distributed(config):
        import tempfile

        return Path(tempfile.mkdtemp(prefix="glshade-snapshot-claims-"))
    return None


SESSION = pytest.StashKey[SnapshotSession]()


@pytest.hookimpl(optionalhook=True)
def pytest_configure_node(node: Any) -> None:
    """pytest-xdist, on the controller: give each worker the run's claims folder."""
    from glshade.snapshot.claims import CLAIMS_KEY

    state = node.config.stash.get(SESSION, None)
    if state is not None and state.claims is not None:
        node.workerinput[CLAIMS_KEY] = str(state.claims)


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        f"{MARKER}(**tolerances): glshade snapshot tolerances for a test, class or file "
        "(image, image_pixels, visibility_px, pmd_mm, pmd_um)",
    )
    config.stash[SESSION] = SnapshotSession.from_config(config)


def pytest_report_header(config: pytest.Config) -> str | None:
    state = config.stash.get(SESSION, None)
    if state is None or not (state.update or state.results or state.renderer != "auto"):
        return None
    mode = "writing baselines" if state.update else "comparing"
    return f"glshade snapshots: {mode} in {state.directory} (renderer: {state.renderer})"


def pytest_deselected(items: list[pytest.Item]) -> None:
    if items:
        state = items[0].config.stash.get(SESSION, None)
        if state is not None:
            state.deselected += len(items)


@pytest.fixture(scope="session")
def glshade_station(request: pytest.FixtureRequest):
    """The session's snapshot renderer (GL, or the NumPy oracle where no OpenGL context
    can be made, or where ``--glshade-renderer oracle`` asks), released at the end."""
    from glshade.errors import GlshadeError
    from glshade.snapshot.station import open_station

    state = request.config.stash[SESSION]
    try:
        station = open_station(state.renderer)
    except GlshadeError as exc:
        message = f"glshade snapshots: {exc}"
        station = None
    if station is None:
        pytest.fail(message, pytrace=False)  # outside the except: one line
    state.station = station
    if station.fallback:
        warnings.warn(
            pytest.PytestWarning(
                "glshade snapshots are rendered and measured by the NumPy float64 oracle: "
                f"{station.fallback}"
            ),
            stacklevel=1,
        )
    yield station
    station.release()


@pytest.fixture
def glshade_snapshot(request: pytest.FixtureRequest, glshade_station: Station) -> Snapshots:
    """``glshade_snapshot.check(scene, name=..., **tolerances)``: the scene's image and
    numbers against their baseline (see :mod:`glshade.snapshot.plugin`)."""
    return Snapshots(request.config.stash[SESSION], glshade_station, request)


class Snapshots:
    """What the ``glshade_snapshot`` fixture gives a test."""

    def __init__(self, state: SnapshotSession, station: Station, request: pytest.FixtureRequest):
        self._state = state
        self._station = station
        self._request = request
        self._unnamed = 0

    @property
    def directory(self) -> Path:
        """The folder this session's baselines are in."""
        return self._state.directory

    @property
    def renderer(self) -> str:
        """What renders and measures: the GL renderer string, or the NumPy oracle."""
        return self._station.identity

    def check(
        self, scene: Scene | str | os.PathLike[str], name: str | None = None, **tolerances: Any
    ) -> Comparison | None:
        """Render and measure ``scene`` (a Scene, or a scene file's path: relative to the
        test file's folder) and compare with baseline ``name`` (default: the test's name).
        Fails the test, in one paragraph, where the image or a number moved beyond its
        tolerance or no baseline exists. Returns the comparison (None when writing)."""
        from glshade.errors import GlshadeError

        try:
            return self._check(scene, name, tolerances)
        except GlshadeError as exc:
            message = f"glshade snapshot: {exc}"
        pytest.fail(message, pytrace=False)  # outside the except: no chained exception shown

    # ------------------------------------------------------------------ steps
    def _check(self, scene: Any, name: str | None, overrides: dict[str, Any]) -> Comparison | None:
        from glshade.errors import GlshadeError
        from glshade.snapshot import baseline as stored

        name = stored.check_name(self._name(name))
        tolerances = self._tolerances(overrides)
        scene, table = self._scene(scene)
        self._claim(name)
        shot = self._station.shoot(scene, table)
        directory = self._state.directory
        scene_file = _plain(scene.to_file_dict(directory, climb=True))
        if self._state.update:
            self._write(name, scene, scene_file, shot)
            self._collided(name)
            return None
        if not stored.exists(directory, name):
            self._missing(name, scene_file, shot)
        try:
            baseline = stored.read(directory, name)
        except GlshadeError as exc:  # a baseline glshade cannot read: kept in the summary
            self._record(name, "broken", str(exc), shot, scene_file)
            raise
        return self._compare(name, baseline, shot, tolerances, scene_file)

    def _name(self, name: str | None) -> str:
        if name is not None:
            return name
        self._unnamed += 1
        if self._unnamed > 1:
            from glshade.errors import GlshadeError

            raise GlshadeError("a test that checks more than one snapshot names each: name=...")
        return "".join(c if c.isalnum() or c in "._+-" else "_" for c in self._request.node.name)

    def _tolerances(self, overrides: dict[str, Any]) -> Tolerances:
        from glshade.snapshot.tolerance import DEFAULT

        tolerances = DEFAULT
        markers = list(self._request.node.iter_markers(MARKER))  # the closest first
        for marker in reversed(markers):
            if marker.args:
                from glshade.errors import GlshadeError

                raise GlshadeError(f"{MARKER}: takes keywords only, got {marker.args!r}")
            tolerances = tolerances.with_overrides(marker.kwargs, f"@pytest.mark.{MARKER}")
        return tolerances.with_overrides(overrides, "check()")

    def _scene(self, scene: Any) -> tuple[Scene, MeasureTable | None]:
        """The scene checked, and its file's ``[measure]`` (None for a Scene given)."""
        from glshade.errors import GlshadeError
        from glshade.instruments.table import file_measure_table
        from glshade.scene import Scene

        if isinstance(scene, (str, os.PathLike)):
            path = Path(scene)
            if not path.is_absolute():
                path = Path(self._request.path).parent / path
            loaded = Scene.load(path)
            return loaded, file_measure_table(path, loaded.active.emitter.measured_by)
        if not isinstance(scene, Scene):
            raise GlshadeError(
                f"check(): scene must be a glshade Scene or a scene file's path, got "
                f"{type(scene).__name__}"
            )
        return scene, None

    def _claim(self, name: str) -> None:
        from glshade.errors import GlshadeError
        from glshade.snapshot import claims

        test = self._request.node.nodeid
        other = self._state.checked.setdefault(name, test)
        if other != test:
            raise GlshadeError(
                f"snapshot name {name!r} is checked by {other} already; give each check its "
                "own name"
            )
        if self._state.claims is not None:  # the other workers' tests (pytest-xdist)
            holder = claims.claim(self._state.claims, name, test)
            if holder is not None:
                raise GlshadeError(claims.collision_line(name, [holder, test]))

    def _collided(self, name: str) -> None:
        """Fail where another worker's test checked ``name`` meanwhile (pytest-xdist)."""
        from glshade.errors import GlshadeError
        from glshade.snapshot import claims

        if self._state.claims is not None:
            tests = claims.collided(self._state.claims, name)
            if tests:
                raise GlshadeError(claims.collision_line(name, tests))

    def _write(self, name: str, scene: Scene, scene_file: dict, shot: Shot) -> None:
        import glshade
        from glshade.snapshot.baseline import Baseline

        Baseline(
            name, shot.image, shot.numbers, scene_file,
            self._station.identity, scene.render.precision, glshade.__version__,
        ).write(self._state.directory)  # fmt: skip
        self._record(name, "written", f"wrote {name}.png and {name}.json", shot, scene_file)

    def _missing(self, name: str, scene_file: dict, shot: Shot) -> None:
        command = f"pytest {shlex.quote(self._request.node.nodeid)} --glshade-update"
        text = (
            f"snapshot {name!r} has no baseline in {self._state.directory}; create it with: "
            f"{command}"
        )
        self._record(name, "missing", text, shot, scene_file)
        pytest.fail(text, pytrace=False)

    def _compare(
        self, name: str, baseline: Baseline, shot: Shot, tolerances: Tolerances, scene_file: dict
    ) -> Comparison:
        from glshade.snapshot.compare import compare, scene_changes

        result = compare(name, baseline, shot, tolerances, self._station.identity)
        if result.passed:
            self._record(name, "passed", "", shot, scene_file, baseline, result)
            return result
        text = result.message()
        changed = scene_changes(baseline.scene, scene_file)
        if changed:
            text += f"; the scene is not the baseline's: {changed}"
        if self._state.results is not None:
            text += f"; see {self._state.results / 'index.html'}"
        self._record(name, "moved", text, shot, scene_file, baseline, result)
        pytest.fail(text, pytrace=False)

    def _record(
        self,
        name: str,
        outcome: str,
        detail: str,
        shot: Shot,
        scene_file: dict,
        baseline: Baseline | None = None,
        result: Comparison | None = None,
    ) -> None:
        from glshade.snapshot.report import Entry, scene_text, write_images

        images: dict[str, str] = {}
        folder = self._state.results
        if folder is not None and outcome in ("moved", "missing", "broken"):
            tolerance = result.tolerances.image if result is not None else 0.0
            expected = baseline.image if baseline is not None else None
            _make_results(folder)
            images = write_images(folder, name, shot.image, expected, tolerance)
        self._state.entries.append(
            Entry(
                name=name,
                test=self._request.node.nodeid,
                outcome=outcome,
                detail=detail,
                renderer=self._station.identity,
                baseline_renderer=baseline.renderer if baseline is not None else "",
                comparison=result,
                numbers=shot.numbers,
                expected_numbers=baseline.numbers if baseline is not None else {},
                scene_toml=scene_text(scene_file),
                images=images,
            )
        )


def _make_results(folder: Path) -> None:
    """The results folder, made where missing (one line where it cannot be)."""
    from glshade.errors import GlshadeError

    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise GlshadeError(
            f"--glshade-results {folder}: cannot create it ({exc.strerror or exc})"
        ) from None
    if not folder.is_dir():
        raise GlshadeError(f"--glshade-results {folder}: is not a directory")


def _plain(data: dict) -> dict:
    """``data`` as it reads back from JSON (tuples become lists)."""
    return json.loads(json.dumps(data))


# --------------------------------------------------------------------- the session's end
def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    state = session.config.stash.get(SESSION, None)
    if state is None or hasattr(session.config, "workerinput"):
        return
    quiet = (pytest.ExitCode.OK, pytest.ExitCode.NO_TESTS_COLLECTED)
    if _distributed(session.config):  # the controller: the workers' collisions
        state.problems += _collisions(state)
        if state.problems and session.exitstatus in quiet:
            session.exitstatus = pytest.ExitCode.TESTS_FAILED
        return
    state.unused = _unused(state)
    if state.unused and state.fail_unused and session.exitstatus in quiet:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED
    if state.results is not None and state.entries:
        _write_summary(state)
        if state.problems and session.exitstatus in quiet:
            session.exitstatus = pytest.ExitCode.TESTS_FAILED


def _collisions(state: SnapshotSession) -> list[str]:
    """The controller's lines for every name two workers' tests checked; the claims
    folder removed."""
    import shutil

    from glshade.snapshot import claims

    if state.claims is None or not state.claims.is_dir():
        return []
    found = claims.collisions(state.claims)
    shutil.rmtree(state.claims, ignore_errors=True)
    return [claims.collision_line(name, tests) for name, tests in found.items()]


def _distributed(config: pytest.Config) -> bool:
    """Under pytest-xdist each worker sees a share of the tests and the controller none:
    neither can tell which baselines went unused, nor write the whole run's summary."""
    if hasattr(config, "workerinput"):
        return True
    return bool(getattr(config.option, "numprocesses", None)) or getattr(
        config.option, "dist", "no"
    ) not in ("no", None)


def _unused(state: SnapshotSession) -> list[str]:
    """The baselines of the folder no test of this session compared (or wrote): reported
    when some test checked a snapshot, or when asked to fail on them."""
    from glshade.snapshot.baseline import stored_names

    if not state.checked and not state.fail_unused:
        return []
    return [name for name in stored_names(state.directory) if name not in state.checked]


def _write_summary(state: SnapshotSession) -> None:
    import glshade
    from glshade.snapshot.report import write_summary

    assert state.results is not None
    header = {
        "glshade": glshade.__version__,
        "renderer": state.station.identity if state.station else "",
        "baselines": str(state.directory),
        "unused baselines": ", ".join(state.unused) or "none",
    }
    if state.station is not None and state.station.fallback:
        header["note"] = f"the NumPy float64 oracle stood in: {state.station.fallback}"
    from glshade.errors import GlshadeError

    try:
        _make_results(state.results)
        write_summary(state.results, state.entries, header)
    except GlshadeError as exc:  # said in the summary, in one line: never a traceback
        state.problems.append(f"no HTML summary: {exc}")


def pytest_terminal_summary(terminalreporter: Any, exitstatus: int, config: pytest.Config) -> None:
    state = config.stash.get(SESSION, None)
    if state is None or not (state.entries or state.unused or state.problems):
        return
    write = terminalreporter.write_line
    terminalreporter.section("glshade snapshots")
    for problem in state.problems:
        write(f"failed: {problem}", red=True)
    if state.entries or state.unused:
        _say_checks(write, state)


def _say_checks(write: Any, state: SnapshotSession) -> None:
    counts: dict[str, int] = {}
    for entry in state.entries:
        counts[entry.outcome] = counts.get(entry.outcome, 0) + 1
    done = ", ".join(f"{n} {outcome}" for outcome, n in sorted(counts.items()))
    write(f"{done or 'no snapshot checked'} in {state.directory}")
    if state.station is not None:
        write(f"renderer: {state.station.identity}")
        if state.station.fallback:
            write(f"no OpenGL: compared on the NumPy float64 oracle ({state.station.fallback})")
    if state.unused:
        subset = " (this run selected some tests only)" if state.deselected else ""
        verb = "failed: " if state.fail_unused else ""
        write(
            f"{verb}{len(state.unused)} unused baselines{subset}: "
            + ", ".join(state.unused)
            + "; remove their .png and .json, or run the tests that check them"
        )
    if state.results is not None and state.entries and not state.problems:
        write(f"summary: {state.results / 'index.html'}")
