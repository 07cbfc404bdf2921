"""Progress of a long run, shown where a person watches and kept short where a log does.

On a terminal (``stream.isatty()``) a tqdm bar is drawn, as before. Anywhere else (stderr
captured into a log, a pipe, a CI job) no bar is drawn, since each of its redraws would be
a line of the log: a run that keeps its bar on a terminal (``leave=True``: a study's or a
sweep's cases) prints one line when it completes, ``glshade sweep: 126/126 cases in
84 s``, and a bar that vanishes when done (``leave=False``: one slow frame of
``glshade render``) prints nothing. A run that stops early (an error, Ctrl-C) prints no
progress line: its error line says what happened.
"""

from __future__ import annotations

import sys
import time
from typing import Any, Protocol, TextIO


class Bar(Protocol):
    def update(self, n: int = 1) -> Any: ...

    def close(self) -> None: ...


def progress_bar(
    total: int,
    desc: str,
    unit: str,
    *,
    initial: int = 0,
    leave: bool = True,
    enabled: bool = True,
    stream: TextIO | None = None,
    terminal: bool | None = None,
) -> Bar | None:
    """The progress of ``total`` ``unit``s (``initial`` of them done before): a tqdm bar
    on ``stream`` (default stderr) where it is a terminal, else a :class:`FinalLine`; None
    where not ``enabled`` (``--no-progress``). ``terminal`` overrides what
    ``stream.isatty()`` says."""
    if not enabled:
        return None
    stream = stream if stream is not None else sys.stderr
    if terminal is None:
        terminal = _isatty(stream)
    if not terminal:
        return FinalLine(total, desc, unit, initial=initial, leave=leave, stream=stream)
    from tqdm import tqdm

    return tqdm(
        total=total,
        initial=initial,
        unit=unit,
        desc=desc,
        leave=leave,
        file=stream,
        dynamic_ncols=True,
    )


class FinalLine:
    """A bar for a log: counts, and when closed complete prints one line (``leave``)."""

    def __init__(
        self, total: int, desc: str, unit: str, *, initial: int, leave: bool, stream: TextIO
    ) -> None:
        self.total, self.desc, self.unit = total, desc, unit
        self.initial = self.n = initial
        self.leave, self.stream = leave, stream
        self.start = time.perf_counter()
        self.closed = False

    def update(self, n: int = 1) -> None:
        self.n += n

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        if self.leave and self.n >= self.total:
            print(self.line(time.perf_counter() - self.start), file=self.stream, flush=True)

    def line(self, seconds: float) -> str:
        """``glshade sweep: 126/126 cases in 84 s (100 this run)``."""
        units = self.unit if self.total == 1 else self.unit + "s"
        took = f"{seconds:.1f} s" if seconds < 10 else f"{seconds:.0f} s"
        this_run = f" ({self.n - self.initial} this run)" if self.initial else ""
        return f"{self.desc}: {self.n}/{self.total} {units} in {took}{this_run}"


def _isatty(stream: TextIO) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):  # a closed or odd stream: not a terminal
        return False
