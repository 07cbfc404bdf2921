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

    @classmethod
    def from_config(cls, config: pytest.Config) -> SnapshotSession:
        base = config.inipath.parent if config.inipath is not None else config.rootpath
        results = config.getoption("glshade_results")
        return cls(
            directory=(base / str(config.getini("glshade_snapshot_dir"))).resolve(),
            update=bool(config.getoption("glshade_update")),
            results=_results_folder(results) if results else None,
            fail_unused=bool(config.getoption("glshade_fail_unused")),
            renderer=str(config.getoption("glshade_renderer")),
        )


def _results_folder(text: str) -> Path:
    """``--glshade-results``'s folder, or a usage error where something else is there."""
    folder = Path(text).resolve()
    if folder.exists() and not folder.is_dir():
        raise pytest.UsageError(f"--glshade-results {text}: is not a directory")
    return folder


SESSION = pytest.StashKey[SnapshotSession]()


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
        pytest.fail(f"glshade snapshots: {exc}", pytrace=False)
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
            pytest.fail(f"glshade snapshot: {exc}", pytrace=False)

    # ------------------------------------------------------------------ steps
    def _check(self, scene: Any, name: str | None, overrides: dict[str, Any]) -> Comparison | None:
        from glshade.errors import GlshadeError
        from glshade.snapshot import baseline as stored

        name = stored.check_name(self._name(name))
        tolerances = self._tolerances(overrides)
        scene = self._scene(scene)
        self._claim(name)
        shot = self._station.shoot(scene)
        directory = self._state.directory
        scene_file = _plain(scene.to_file_dict(directory, climb=True))
        if self._state.update:
            self._write(name, scene, scene_file, shot)
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

    def _scene(self, scene: Any) -> Scene:
        from glshade.errors import GlshadeError
        from glshade.scene import Scene

        if isinstance(scene, (str, os.PathLike)):
            path = Path(scene)
            if not path.is_absolute():
                path = Path(self._request.path).parent / path
            return Scene.load(path)
        if not isinstance(scene, Scene):
            raise GlshadeError(
                f"check(): scene must be a glshade Scene or a scene file's path, got "
                f"{type(scene).__name__}"
            )
        return scene

    def _claim(self, name: str) -> None:
        from glshade.errors import GlshadeError

        test = self._request.node.nodeid
        other = self._state.checked.setdefault(name, test)
        if other != test:
            raise GlshadeError(
                f"snapshot name {name!r} is checked by {other} already; give each check its "
                "own name"
            )

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
            folder.mkdir(parents=True, exist_ok=True)
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


def _plain(data: dict) -> dict:
    """``data`` as it reads back from JSON (tuples become lists)."""
    return json.loads(json.dumps(data))


# --------------------------------------------------------------------- the session's end
def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    state = session.config.stash.get(SESSION, None)
    if state is None or _distributed(session.config):
        return
    state.unused = _unused(state)
    quiet = (pytest.ExitCode.OK, pytest.ExitCode.NO_TESTS_COLLECTED)
    if state.unused and state.fail_unused and session.exitstatus in quiet:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED
    if state.results is not None and state.entries:
        _write_summary(state)


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
    state.results.mkdir(parents=True, exist_ok=True)
    write_summary(state.results, state.entries, header)


def pytest_terminal_summary(terminalreporter: Any, exitstatus: int, config: pytest.Config) -> None:
    state = config.stash.get(SESSION, None)
    if state is None or not (state.entries or state.unused):
        return
    write = terminalreporter.write_line
    terminalreporter.section("glshade snapshots")
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
    if state.results is not None and state.entries:
        write(f"summary: {state.results / 'index.html'}")
