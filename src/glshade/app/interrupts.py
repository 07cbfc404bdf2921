"""Ctrl-C noted as it happens: what the command's entry point (:mod:`glshade.app.entry`)
and the command line (:mod:`glshade.app.cli`) share to tell an error a Ctrl-C caused
from a real one.

A Ctrl-C that lands inside a C extension's import (NumPy's) does not arrive as
``KeyboardInterrupt``: the extension's import fails, and NumPy raises an ``ImportError``
that names a module it could not load. :class:`InterruptWatch` notes every SIGINT, so such
an error is reported as the interruption it was.
"""

from __future__ import annotations

import signal


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
