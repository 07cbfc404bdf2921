"""The ``glshade`` command's entry point: the command line (:mod:`glshade.app.cli`) loaded
and run inside a guard, so that Ctrl-C pressed while Python imports glshade's modules (a
few hundred milliseconds of start-up) ends with one line and exit code 130, as it does at
any later moment, never a traceback.

A Ctrl-C that lands inside a C extension's import (NumPy's) does not arrive as
``KeyboardInterrupt``: the extension's import fails, and NumPy raises an ``ImportError``
that names a module it could not load. :class:`InterruptWatch` notes every SIGINT, so such
an error is told apart from a broken installation.
"""

from __future__ import annotations

import signal
import sys

EXIT_INTERRUPTED = 130
#: The exit code of a failure that is not the user's input (here: glshade cannot start).
EXIT_DEFECT = 1


class InterruptWatch:
    """While held (``with``), SIGINT raises ``KeyboardInterrupt`` as Python's own handler
    does, and is noted (:attr:`seen`); on leaving, SIGINT gets ``release_to`` (default:
    the handler it had)."""

    def __init__(self, release_to: object = None) -> None:
        self.seen = False
        self._previous: object = None
        self._release_to = release_to

    def _on_sigint(self, signum: int, frame: object) -> None:
        self.seen = True
        raise KeyboardInterrupt

    def __enter__(self) -> InterruptWatch:
        self._previous = signal.signal(signal.SIGINT, self._on_sigint)
        return self

    def __exit__(self, *exc: object) -> None:
        after = self._previous if self._release_to is None else self._release_to
        signal.signal(signal.SIGINT, after)  # type: ignore[arg-type]


def main() -> int:
    """Run the command line of this process (``sys.argv``); returns its exit code."""
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
