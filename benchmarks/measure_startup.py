"""Where the time of one ``glshade measure`` process goes: a breakdown by stage
(docs/BENCHMARKS.md, "`glshade measure` start-up").

    python benchmarks/measure_startup.py [--runs 10] [--tree NAME=SRC ...] [--bytecode]
        [-- measure flags…]

Each run is a fresh interpreter that runs ``glshade.app.cli.main()`` on the command line
``glshade measure --json …`` (as the ``glshade`` script does) with timers wrapped around
the stages; each stage's time is its own (a stage called inside another is not counted
twice):

- start + exit: the interpreter's start-up and shut-down (the process's wall time less
  what the script itself timed);
- imports: ``import glshade.app.cli`` and the modules the command imports on first use
  (measured apart: every module a first run left in ``sys.modules`` is imported before
  the timed command);
- parser, scene: building the argument parser; the scene from the flags and its warnings;
- context: the EGL context; compose, compile: the GLSL composed, the program compiled
  and linked;
- trace: the draws and their read-back; analysis: the metric (``Baseline``); status:
  the status and the stripes' contrast; release: the renderer and its context;
- output: everything else in the command (the record, the JSON line).

Beside them, the wall time of the plain ``glshade measure --json`` process (no timers,
as ``/usr/bin/time`` sees it). ``--tree NAME=SRC`` (repeatable) runs the glshade whose
sources are in ``SRC`` (``PYTHONPATH``; default: the one installed); the trees run
alternately, run after run, so that a machine whose speed drifts treats them alike.
``--bytecode``: each tree also with Python's bytecode files (a cache folder filled by a
first run), as an installed package has them; without it the runs inherit this
environment's ``PYTHONDONTWRITEBYTECODE``. The minimum and the median of ``--runs`` runs
are printed as a Markdown table.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

#: The child: imports, then the command with its stages timed. argv[1]: the JSON list of
#: modules to import first; argv[2:]: the measure flags.
CHILD = r"""
import time
_t0 = time.perf_counter()
import json, sys, importlib, functools
import glshade.app.cli as cli
_t_cli = time.perf_counter() - _t0
for _name in json.loads(sys.argv[1]):
    if _name not in sys.modules:
        try:
            importlib.import_module(_name)
        except Exception:
            pass
_t_imports = time.perf_counter() - _t0

spent, stack = {}, []

def timed(stage, owner, name):
    inner = getattr(owner, name)
    @functools.wraps(inner)
    def wrapper(*args, **kwargs):
        stack.append(0.0)
        start = time.perf_counter()
        try:
            return inner(*args, **kwargs)
        finally:
            total = time.perf_counter() - start
            nested = stack.pop()
            spent[stage] = spent.get(stage, 0.0) + total - nested
            if stack:
                stack[-1] += total
    setattr(owner, name, wrapper)

from glshade.app import cli as c
try:  # the command's own module (a tree from before the commands had modules: the CLI's)
    from glshade.app.commands import measure as cm
except ImportError:
    cm = c
from glshade.gpu import context as gc, renderer as gr, compose as gp
from glshade.instruments.stripes import single as ms
from glshade.metrics import visibility as mv
timed("parser", c, "build_parser")
timed("scene", cm, "scene_from_args")
timed("scene", cm, "scene_warnings")
timed("context", gc.GLContext, "__init__")
timed("compose", gr, "compose")
timed("compile", gr.Renderer, "_program")
timed("trace", gr.Renderer, "_draw")
for _hook in ("_trace_pair",):  # a renderer that traces both maps in one call
    if hasattr(gr.Renderer, _hook):
        timed("trace", gr.Renderer, _hook)
timed("analysis", mv.Baseline, "__init__")
timed("analysis", mv.Baseline, "measure")
timed("status", ms, "judged")
timed("release", gr.Renderer, "release")
_t1 = time.perf_counter()
sys.argv = ["glshade", "measure", "--json", *sys.argv[2:]]
code = cli.main()  # as the glshade script runs it: the process's own command line
_t_command = time.perf_counter() - _t1
spent["output"] = _t_command - sum(spent.values())
spent["imports"] = _t_imports
spent["of which glshade.app.cli"] = _t_cli
spent["script"] = time.perf_counter() - _t0
sys.stderr.write("BREAKDOWN " + json.dumps(spent) + "\n")
sys.exit(code)
"""

#: Lists the modules the command leaves imported.
MODULES = r"""
import sys, glshade.app.cli as cli, json
code = cli.main(["measure", "--json", *sys.argv[1:]])
sys.stderr.write("MODULES " + json.dumps(list(sys.modules)) + "\n")
"""

ORDER = (
    "start + exit",
    "imports",
    "of which glshade.app.cli",
    "parser",
    "scene",
    "context",
    "compose",
    "compile",
    "trace",
    "analysis",
    "status",
    "release",
    "output",
)


def _last_line(text: str, tag: str) -> str:
    return next(line for line in reversed(text.splitlines()) if line.startswith(tag))[
        len(tag) + 1 :
    ]


def breakdown(flags: list[str], env: dict[str, str] | None = None) -> tuple[dict[str, float], str]:
    """One fresh process's stages (seconds) and what the command printed (``env``: the
    child's environment, default this one's)."""
    found = subprocess.run(
        [sys.executable, "-c", MODULES, *flags], capture_output=True, text=True, check=True, env=env
    )
    modules = json.loads(_last_line(found.stderr, "MODULES"))
    start = time.perf_counter()
    run = subprocess.run(
        [sys.executable, "-c", CHILD, json.dumps(modules), *flags],
        capture_output=True,
        text=True,
        check=True,
        env=env,
    )
    wall = time.perf_counter() - start
    spent = json.loads(_last_line(run.stderr, "BREAKDOWN"))
    spent["start + exit"] = wall - spent.pop("script")
    spent["wall"] = wall
    return spent, run.stdout


def plain_wall(flags: list[str], env: dict[str, str] | None = None) -> float:
    """The wall time of the command itself, no timers (as ``/usr/bin/time`` sees it)."""
    command = shutil.which("glshade") or "glshade"
    start = time.perf_counter()
    subprocess.run([command, "measure", "--json", *flags], capture_output=True, check=True, env=env)
    return time.perf_counter() - start


def _variants(trees: list[str], bytecode: bool, cache: str) -> list[tuple[str, dict]]:
    """(column name, environment) of every tree, with and without bytecode files."""
    out = []
    for spec in trees or ["installed="]:
        name, _, src = spec.partition("=")
        env = dict(os.environ)
        if src:
            env["PYTHONPATH"] = os.path.abspath(src)
        out.append((name, env))
        if bytecode:
            cached = {**env, "PYTHONPYCACHEPREFIX": os.path.join(cache, name)}
            writing = {k: v for k, v in cached.items() if k != "PYTHONDONTWRITEBYTECODE"}
            plain_wall([], writing)  # fills the folder
            out.append((f"{name}, bytecode", cached))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--tree", action="append", default=[], metavar="NAME=SRC")
    parser.add_argument("--bytecode", action="store_true")
    parser.add_argument("flags", nargs="*", help="measure flags (after --)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as cache:
        variants = _variants(args.tree, args.bytecode, cache)
        runs: dict[str, list[dict[str, float]]] = {name: [] for name, _ in variants}
        for _ in range(args.runs):
            for name, env in variants:
                spent = breakdown(args.flags, env)[0]
                spent["wall, plain command"] = plain_wall(args.flags, env)
                runs[name].append(spent)
    print(
        f"`glshade measure --json {' '.join(args.flags)}`: {args.runs} runs of each, "
        f"alternately; ms, min / median\n"
    )
    print("| stage | " + " | ".join(runs) + " |")
    print("|---|" + "---:|" * len(runs))
    for stage in (*ORDER, "wall", "wall, plain command"):
        cells = []
        for values in ([run.get(stage, 0.0) for run in r] for r in runs.values()):
            cells.append(f"{1e3 * min(values):.0f} / {1e3 * statistics.median(values):.0f}")
        print(f"| {stage} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
