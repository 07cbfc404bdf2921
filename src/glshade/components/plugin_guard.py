"""A plug-in's code run so that nothing it raises can take glshade down.

A plug-in runs its own code when glshade imports it and when glshade reads what it
declares (its components' names, parameters, tables). :func:`run_plugin_code` runs such
code and turns everything it lets out into :class:`PluginRefused`, whose message says
what it was in one line: ``SystemExit`` (which would end every glshade command with the
plug-in's exit code, silently), ``KeyboardInterrupt`` and ``GeneratorExit`` included,
since a plug-in that raises them is a broken plug-in, not a user who pressed Ctrl-C.

A real Ctrl-C pressed meanwhile stays the user's: while the plug-in's code runs (in the
main thread, where Python delivers signals), SIGINT is noted on its way to the handler it
already had, and once noted, whatever the code lets out (the ``KeyboardInterrupt``
itself, or an ``ImportError`` a C extension made of it), or even nothing when the plug-in
swallowed it, ends as ``KeyboardInterrupt``. In another thread no signal arrives, so
every exception there is the plug-in's.

The guard is against mistakes, not against malice: a plug-in runs with the user's
rights and can end the process (``os._exit``) or never return; nothing here stops that.
Importing this module changes nothing.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator
from types import FrameType
from typing import TypeVar

from glshade.errors import GlshadeError, printable

_T = TypeVar("_T")


class PluginRefused(GlshadeError):
    """A plug-in's code failed (its message: what it raised, in one line) or what it
    declares is malformed."""


def run_plugin_code(call: Callable[[], _T]) -> _T:
    """``call()``, a plug-in's code: its result, or :class:`PluginRefused` for anything
    it raises; ``KeyboardInterrupt`` when the user pressed Ctrl-C while it ran."""
    with _sigint_noted() as pressed:
        try:
            result = call()
        except PluginRefused:
            if pressed():
                raise KeyboardInterrupt from None
            raise
        except BaseException as exc:  # SystemExit, KeyboardInterrupt, GeneratorExit too
            if pressed():
                raise KeyboardInterrupt from None
            raise PluginRefused(described(exc)) from None
        if pressed():  # the plug-in swallowed the user's Ctrl-C
            raise KeyboardInterrupt
        return result


def described(exc: BaseException) -> str:
    """``exc`` as one line of at most about 300 characters: its class, then its message
    (which may itself fail to print)."""
    kind = type(exc).__name__
    try:
        text = " ".join(str(exc).split())
    except Exception:
        text = "(its message cannot be printed)"
    text = printable(text)
    text = text if len(text) <= 300 else text[:297] + "..."
    return f"{kind}: {text}" if text else kind


@contextlib.contextmanager
def _sigint_noted() -> Iterator[Callable[[], bool]]:
    """While held, a SIGINT is noted (the function yielded says whether one came) and
    then handled as before; only in the main thread, and only where SIGINT has a Python
    handler (one that raises KeyboardInterrupt); the handler is put back on leaving."""
    seen = [False]
    previous = None
    if threading.current_thread() is threading.main_thread():
        current = signal.getsignal(signal.SIGINT)
        if callable(current):
            handler = current

            def noting(signum: int, frame: FrameType | None) -> object:
                seen[0] = True
                return handler(signum, frame)

            with contextlib.suppress(ValueError, OSError):
                signal.signal(signal.SIGINT, noting)
                previous = current
    try:
        yield lambda: seen[0]
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)
