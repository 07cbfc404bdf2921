"""A broken plug-in cannot take glshade down: one that exits, interrupts or raises at its
import, or declares a malformed component, is left out with one warning naming it (its
entry point and module) and what went wrong; every other command works, ``--version``
and ``--help`` too; a scene that asks for it is refused in one line; a real Ctrl-C stays
the user's. The plug-ins are modules of ``tests/plugins/hostile``, declared by a
``.dist-info`` folder written into a temporary folder on ``PYTHONPATH`` (as an installed
package declares them); the commands run as a user runs them (a fresh interpreter)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from importlib.metadata import EntryPoint
from pathlib import Path

import pytest

from glshade import __version__
from glshade.components import registry as reg
from glshade.components.plugin_guard import PluginRefused, run_plugin_code
from glshade.errors import GlshadeWarning
from glshade_process import run_glshade

REPO = Path(__file__).resolve().parent.parent
HOSTILE = "tests.plugins.hostile"

#: entry point name -> (its value, what the warning must say went wrong)
BROKEN = {
    "exits": (f"{HOSTILE}.exits", "does not load: SystemExit: 0"),
    "interrupts": (f"{HOSTILE}.interrupts", "does not load: KeyboardInterrupt"),
    "closes": (f"{HOSTILE}.generator_exit", "does not load: GeneratorExit: closed"),
    "listed": (
        f"{HOSTILE}.declarations:named_by_a_list",
        "does not fit: a surface component's name must be a letter, then letters, digits, "
        "'_' or '-' (at most 64), got ['wavy']",
    ),
    "raising": (
        f"{HOSTILE}.declarations:params_raise",
        "does not fit: surface component 'wavy': RuntimeError: no table today",
    ),
    "worded": (
        f"{HOSTILE}.declarations:ranked_by_word",
        "does not fit: surface component 'wavy': its rank must be a finite number, got 'high'",
    ),
    "texts": (
        f"{HOSTILE}.declarations:params_of_text",
        "does not fit: surface component 'wavy': its params must be a tuple of "
        "glshade.params.Param, got ('surface.amplitude',)",
    ),
    "pathlike": (
        f"{HOSTILE}.declarations:named_like_a_path",
        "does not fit: a surface component's name must be",
    ),
    "clashing": (
        f"{HOSTILE}.declarations:takes_a_builtin_name",
        "does not fit: surface component 'sphere' is already registered",
    ),
}


def _warning(entry: str) -> str:
    value, problem = BROKEN[entry]
    return f"glshade: warning: plug-in {entry!r} ({value}) {problem}"


def _installed(tmp_path: Path, entries: dict[str, str]) -> dict[str, str]:
    """The environment of a glshade that sees ``entries`` (name -> value) declared in
    the group by an installed distribution."""
    info = tmp_path / "site" / "hostile_plugin-1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: hostile-plugin\nVersion: 1.0\n")
    lines = "".join(f"{name} = {value}\n" for name, value in entries.items())
    (info / "entry_points.txt").write_text(f"[{reg.ENTRY_POINT_GROUP}]\n{lines}")
    return {"PYTHONPATH": os.pathsep.join([str(tmp_path / "site"), str(REPO)])}


def _clean(done: subprocess.CompletedProcess) -> list[str]:
    """stderr's lines, after checking that none is a traceback or blames glshade."""
    assert "Traceback" not in done.stderr and "bug in glshade" not in done.stderr, done.stderr
    return done.stderr.splitlines()


@pytest.mark.parametrize("entry", list(BROKEN))
def test_help_works_beside_a_broken_plugin_which_is_named_in_one_line(tmp_path, entry):
    env = _installed(tmp_path, {entry: BROKEN[entry][0]})
    done = run_glshade("--help", cwd=tmp_path, env=env)
    assert done.returncode == 0 and done.stdout.startswith("usage: glshade")
    lines = _clean(done)
    assert len(lines) == 1 and lines[0].startswith(_warning(entry)), lines
    assert lines[0].endswith("; glshade runs without it")


@pytest.mark.parametrize("entry", ["exits", "interrupts", "raising"])
def test_version_works_beside_a_broken_plugin(tmp_path, entry):
    env = _installed(tmp_path, {entry: BROKEN[entry][0]})
    done = run_glshade("--verbose", "--version", cwd=tmp_path, env=env)
    assert (done.returncode, done.stdout, done.stderr) == (0, f"glshade {__version__}\n", "")


def test_only_a_version_asked_before_any_command_skips_loading():
    from glshade.app.entry import asks_version

    assert asks_version(["--version"]) and asks_version(["--verbose", "--version"])
    assert not asks_version([]) and not asks_version(["measure", "--version"])
    assert not asks_version(["--help", "--version"])  # the parser shows the help first


def test_a_command_that_does_not_use_the_broken_plugins_works(tmp_path):
    """Two broken plug-ins and a good one (the toy tilted plane): the measurement runs,
    exit code 0, one warning line for each broken one, and the good one is offered."""
    entries = {name: BROKEN[name][0] for name in ("exits", "raising")}
    entries["tilted"] = "tests.plugins.surface_tilted:Tilted"
    env = _installed(tmp_path, entries)
    done = run_glshade("measure", "--size", "16", "--json", cwd=tmp_path, env=env)
    assert done.returncode == 0, done.stderr
    assert "visibility_px" in json.loads(done.stdout)
    lines = _clean(done)
    assert sorted(lines) == sorted(_warning(name) + "; glshade runs without it" for name in BROKEN
                                   if name in ("exits", "raising"))  # fmt: skip
    offered = run_glshade("measure", "--help", cwd=tmp_path, env=env).stdout
    assert "tilted" in offered and "wavy" not in offered


def test_a_scene_that_asks_for_the_broken_plugin_is_refused(tmp_path):
    env = _installed(tmp_path, {"raising": BROKEN["raising"][0]})
    done = run_glshade("measure", "--size", "16", "--surface", "wavy", cwd=tmp_path, env=env)
    assert done.returncode == 2 and done.stdout == ""
    lines = _clean(done)
    assert len(lines) == 2 and lines[0].startswith(_warning("raising")), lines
    assert lines[1].startswith("glshade: error: ") and "'wavy'" in lines[1]


def test_ctrl_c_during_a_plugins_import_is_the_users_interruption(tmp_path):
    """The plug-in turns the KeyboardInterrupt into an ImportError (as a C extension's
    import does): the user pressed Ctrl-C, so glshade says it was interrupted (130)."""
    env = {**os.environ, **_installed(tmp_path, {"slow": f"{HOSTILE}.slow"})}
    process = subprocess.Popen(
        [sys.executable, "-m", "glshade", "measure", "--size", "16"],
        cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert process.stdout is not None
        assert process.stdout.readline() == "plug-in importing\n"
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=60)
    finally:
        process.kill()
    assert process.returncode == 130, err
    assert err.splitlines() == ["glshade: interrupted"]


# ------------------------------------------------------------------ in one process
def _registry_with(monkeypatch, entries: dict[str, str]) -> reg.Registry:
    """A registry built afresh (not the process's own) from glshade's components and
    ``entries``; the warnings it gives are checked by the caller."""
    points = [EntryPoint(name, value, reg.ENTRY_POINT_GROUP) for name, value in entries.items()]
    monkeypatch.setattr(reg, "only_builtin_declared", lambda path=None: False)
    monkeypatch.setattr(reg, "_entry_points", lambda: points)
    return reg.registry.__wrapped__()


@pytest.mark.parametrize("entry", list(BROKEN))
def test_the_registry_leaves_a_broken_plugin_out_whole(monkeypatch, entry):
    own = reg.registry()
    with pytest.warns(GlshadeWarning) as caught:
        built = _registry_with(monkeypatch, {entry: BROKEN[entry][0]})
    value, problem = BROKEN[entry]
    assert [(f.entry, f.value) for f in built.failures] == [(entry, value)]
    assert built.failures[0].problem.startswith(problem)
    assert [str(w.message) for w in caught] == [built.failures[0].line()]
    assert {(c.slot, c.name) for c in built.components()} == {
        (c.slot, c.name) for c in own.components()
    }  # "rippled", valid beside the clashing "sphere", went with it
    assert type(built.get("surface", "sphere")) is type(own.get("surface", "sphere"))


def test_a_good_plugin_beside_broken_ones_is_registered(monkeypatch):
    entries = {"exits": BROKEN["exits"][0], "tilted": "tests.plugins.surface_tilted:Tilted"}
    with pytest.warns(GlshadeWarning, match="plug-in 'exits'"):
        built = _registry_with(monkeypatch, entries)
    assert "tilted" in built.names("surface")
    assert [f.entry for f in built.failures] == ["exits"]


def test_a_real_ctrl_c_while_plugin_code_runs_stays_the_users():
    before = signal.getsignal(signal.SIGINT)

    def pressed_then(after):
        def call():
            try:
                os.kill(os.getpid(), signal.SIGINT)
                for _ in range(10**6):  # the handler runs between two bytecodes
                    pass
            except KeyboardInterrupt:
                after()
            return "done"

        return call

    def as_import_error():
        raise ImportError("a C extension interrupted")

    with pytest.raises(KeyboardInterrupt):
        run_plugin_code(pressed_then(as_import_error))
    with pytest.raises(KeyboardInterrupt):
        run_plugin_code(pressed_then(lambda: None))  # swallowed by the plug-in
    with pytest.raises(PluginRefused, match="^KeyboardInterrupt$"):
        run_plugin_code(lambda: (_ for _ in ()).throw(KeyboardInterrupt))
    with pytest.raises(PluginRefused, match="^SystemExit: 3$"):
        run_plugin_code(lambda: sys.exit(3))
    assert run_plugin_code(lambda: 7) == 7
    assert signal.getsignal(signal.SIGINT) is before
