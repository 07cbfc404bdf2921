"""The ``glshade`` command's entry point: the command line (:mod:`glshade.app.cli`) loaded
and run inside a guard, so that Ctrl-C pressed while Python imports glshade's modules (a
few hundred milliseconds of start-up) ends with one line and exit code 130, as it does at
any later moment, never a traceback.

A Ctrl-C inside a C extension's import arrives as that import's failure: the
:class:`~glshade.app.interrupts.InterruptWatch` tells it apart from a broken installation.
``glshade --version`` is answered before anything else is loaded, so no plug-in, however
broken, can stand in its way.
"""

from __future__ import annotations

import signal
import sys

from glshade.app.interrupts import InterruptWatch

EXIT_INTERRUPTED = 130
#: The exit code of a failure that is not the user's input (here: glshade cannot start).
EXIT_DEFECT = 1


def main() -> int:
    """Run the command line of this process (``sys.argv``); returns its exit code."""
    if asks_version(sys.argv[1:]):  # before anything is loaded: no plug-in can stop it
        from glshade.version import __version__

        print(f"glshade {__version__}")
        return 0
    watch = InterruptWatch(release_to=signal.SIG_DFL)  # then: Ctrl-C during the exit is
    try:  # the default action (the process ends, silently, as interrupted)
        with watch:
            from glshade.app.cli import main as run

            code = run(interrupts=watch)
    except KeyboardInterrupt:
        code = _interrupted()
    except Exception as exc:  # glshade's own modules could not be imported
        code = _interrupted() if watch.seen else _cannot_start(exc)
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    return code


def asks_version(argv: list[str]) -> bool:
    """Whether ``argv`` asks for ``--version`` before any command, as the parser reads it
    (``glshade --verbose --version``)."""
    for arg in argv:
        if arg != "--verbose":
            return arg == "--version"
    return False


def _cannot_start(exc: Exception) -> int:
    """One line for a glshade that cannot import its own modules."""
    text = " ".join(str(exc).split())[:300]
    print(
        f"glshade: error: glshade cannot start: {type(exc).__name__}: {text} (reinstall it: "
        "pip install glshade)",
        file=sys.stderr,
    )
    return EXIT_DEFECT


def _interrupted() -> int:
    print("glshade: interrupted", file=sys.stderr)
    return EXIT_INTERRUPTED
