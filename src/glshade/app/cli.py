"""``glshade`` command line: a thin layer over the library.

Bad input (a malformed file or value, an unknown key, a missing system library or
display, an output path that cannot be written or is not a regular file) prints one
line, ``glshade: error: …``, and exits with code 2. Every output path is checked before
any work starts, and files are written atomically, so nothing is written half-way.
Values that are accepted but implausible print ``glshade: warning: …`` lines. The scene
format, its units and ranges: ``docs/scene-format.md``.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import importlib
import sys
from typing import Protocol, cast

from glshade import __version__
from glshade.app.args import EXIT_USAGE, Parser, check_run_settings, one_line
from glshade.app.interrupts import InterruptWatch
from glshade.errors import GlshadeError, GlshadeWarning, ShaderCompileError
from glshade.files import reading_inputs

EXIT_INTERRUPTED = 130
#: The exit code of an error that is glshade's defect, not the user's.
EXIT_DEFECT = 1


class Command(Protocol):
    """A command's module (:mod:`glshade.app.commands`)."""

    def add(self, sub: argparse._SubParsersAction) -> None:
        """Add the command's parser to ``sub``."""

    def run(self, args: argparse.Namespace) -> int:
        """Run the command on its parsed command line; its exit code."""


#: Every command, in the order ``--help`` lists them; each is the module of that name in
#: :mod:`glshade.app.commands`, imported when its parser is built (:func:`command`), so a
#: command line does not load the other commands' modules.
COMMANDS: tuple[str, ...] = (
    "render",
    "measure",
    "info",
    "paper",
    "view",
    "accuracy",
    "finding3",
    "bench",
    "sweep",
    "optimize",
    "coding",
    "budget",
    "station",
    "decode",
    "twin",
)


def command(name: str) -> Command:
    """The module of the command ``name`` (one of :data:`COMMANDS`)."""
    return cast(Command, importlib.import_module(f"glshade.app.commands.{name}"))


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The command line's parser. ``only``: build only that command's parser (its
    flags, and the modules they need), the others as bare names, which is all a command
    line that starts with it can reach (:func:`command_of`); None: every command, whole
    (``glshade --help``)."""
    parser = Parser(
        prog="glshade",
        description="GPU deflectometry simulator (stripe reflections on glossy surfaces).",
    )
    parser.add_argument("--version", action="version", version=f"glshade {__version__}")
    parser.add_argument("--verbose", action="store_true", help=VERBOSE_HELP)
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for name in COMMANDS:
        if only is None or name == only:
            command(name).add(sub)
        else:
            sub.add_parser(name)
    for command_parser in sub.choices.values():  # also after the command: glshade paper --verbose
        command_parser.add_argument(
            "--verbose", action="store_true", default=argparse.SUPPRESS, help=VERBOSE_HELP
        )
    return parser


VERBOSE_HELP = (
    "show the libraries' log output (Dask, ...) and, for an internal error, its traceback"
)


def command_of(argv: list[str]) -> str | None:
    """The command a command line runs when it starts with one (``measure --json``);
    None otherwise (``--help``, ``--version``, nothing, a typo), for which the whole
    parser is built."""
    return argv[0] if argv and argv[0] in COMMANDS else None


def main(argv: list[str] | None = None, interrupts: InterruptWatch | None = None) -> int:
    """Run one command; returns its exit code (0, 2 for any error the user can fix, 130
    when interrupted, 1 for glshade's own defect). Every outcome is at most one line on
    stderr (warnings aside), never a traceback (unless ``--verbose``).

    ``argv`` None: the process's own command line (``sys.argv``), and the process ends
    when this returns: every object still alive is then frozen out of the garbage
    collector's reach, so that the interpreter's shut-down does not traverse them all
    again (about 40 ms of a short command such as ``glshade measure``).
    ``interrupts``: the entry point's record of SIGINT (an error that a Ctrl-C caused is
    reported as the interruption it was)."""
    argv_given = sys.argv[1:] if argv is None else list(argv)
    options = argv_given[: argv_given.index("--")] if "--" in argv_given else argv_given
    verbose = "--verbose" in options  # known before parsing: the parser's own errors obey it
    try:
        with guarded_warnings(verbose), reading_inputs():  # no output over what it reads
            code = _run(argv_given, verbose, interrupts)
    except KeyboardInterrupt:  # between the command's own handlers (start-up, shut-down)
        code = _interrupted(None)
    if argv is None:
        gc.freeze()
    return code


def _run(argv: list[str], verbose: bool, interrupts: InterruptWatch | None) -> int:
    """The command line ``argv`` run; every exception it lets out becomes one line."""
    args = None
    try:  # (the libraries' loggers are quietened where Dask starts: glshade.logs)
        args = build_parser(command_of(argv)).parse_args(argv)
        check_run_settings(args)
        return command(args.command).run(args)
    except SystemExit as exc:  # --help, --version, or a usage error already printed as one line
        return exc.code if isinstance(exc.code, int) else EXIT_USAGE
    except KeyboardInterrupt:
        return _interrupted(args)
    except BrokenPipeError:  # the reader of our output went away (``| head``)
        _silence_stdout()
        return 0
    except ShaderCompileError as exc:  # a composed shader the driver refused: its lines help
        print(f"glshade: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except GlshadeError as exc:
        return _error(str(exc))
    except OSError as exc:  # the file system or the environment refused (disk full, permissions)
        where = f"{exc.filename}: " if exc.filename else ""
        return _error(f"{where}{exc.strerror or exc}")
    except MemoryError:
        return _error("out of memory; try a smaller --size or set GLSHADE_MEMORY_BUDGET_MB lower")
    except RecursionError:
        return _error(
            "the input is nested too deeply to read (a file or value of thousands of levels)"
        )
    except Exception as exc:  # a defect of glshade: one line, exit 1, how to report it
        if interrupts is not None and interrupts.seen:  # a Ctrl-C inside a C extension's import
            return _interrupted(args)
        return _defect(exc, verbose)


def _interrupted(args: argparse.Namespace | None) -> int:
    resumable = args is not None and args.command in ("paper", "sweep", "budget")
    hint = " (finished cases are saved: rerun the same command to resume)" if resumable else ""
    print(f"glshade: interrupted{hint}", file=sys.stderr)
    return EXIT_INTERRUPTED


def _defect(exc: Exception, verbose: bool) -> int:
    """An exception no check foresaw: glshade's defect, not the user's. One line naming it
    and how to report it (``--verbose`` shows the traceback too); exit code 1."""
    if verbose:
        import traceback

        traceback.print_exception(exc, file=sys.stderr)
    text = one_line(str(exc))[:300]
    print(
        f"glshade: internal error: {type(exc).__name__}{': ' if text else ''}{text} (a bug in "
        f"glshade {__version__}: please report it with the command line; --verbose shows the "
        "traceback)",
        file=sys.stderr,
    )
    return EXIT_DEFECT


def _silence_stdout() -> None:
    """Point stdout at /dev/null, so that the interpreter's final flush into a closed pipe
    says nothing."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass


@contextlib.contextmanager
def guarded_warnings(verbose: bool):
    """Python warnings (a library's, NumPy's) print as one ``glshade: warning:`` line each,
    at most once per message, unless ``verbose`` (Python's own form, with the source
    line)."""
    import warnings

    if verbose:
        yield
        return
    shown: set[str] = set()

    def one_line_warning(message, category, filename, lineno, file=None, line=None) -> None:
        text = one_line(str(message))
        if text not in shown:
            shown.add(text)
            kind = "" if issubclass(category, GlshadeWarning) else f"{category.__name__}: "
            print(f"glshade: warning: {kind}{text}", file=sys.stderr)

    with warnings.catch_warnings():
        warnings.showwarning = one_line_warning
        yield


def _error(message: str) -> int:
    print(f"glshade: error: {one_line(message)}", file=sys.stderr)
    return EXIT_USAGE


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
