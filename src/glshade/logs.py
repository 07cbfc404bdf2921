"""The log output of the libraries glshade runs on (Dask, Tornado, asyncio, ...).

glshade reports what went wrong itself, in one line (:class:`glshade.errors.GlshadeError`):
a Dask scheduler that does not answer, a worker that died, a task the cluster cancelled
all reach glshade as exceptions. The same events also reach the libraries' loggers, which
print them again with tracebacks (a worker's ``CommClosedError`` while the cluster shuts
down, ``Timed out trying to connect``), so by default those loggers are quietened:
:func:`quiet_libraries`. ``glshade --verbose`` leaves them as the libraries configure
them. Importing this module changes nothing.
"""

from __future__ import annotations

import contextlib
import logging
import warnings
from collections.abc import Iterator

#: The level each library's logger is set to unless verbose, by logger name (its
#: descendants that set their own level get it too).
#: - ``distributed`` (Dask): CRITICAL. Its ERROR and WARNING lines during a connection or
#:   a shut-down (``CommClosedError``, heartbeats, a nanny killing a slow worker) repeat
#:   what glshade already says or are harmless; everything it logs at those levels reaches
#:   glshade as an exception too.
#: - ``tornado``, ``asyncio``: CRITICAL. Dask's event loops log "Exception in callback",
#:   "Task exception was never retrieved" with tracebacks when a comm closes under them.
#: - ``bokeh`` (Dask's dashboard, which glshade never starts): ERROR.
#: - ``fsspec``, ``matplotlib``, ``PIL``: WARNING (their INFO and DEBUG lines are chatter).
QUIET_LEVELS: dict[str, int] = {
    "distributed": logging.CRITICAL,
    "tornado": logging.CRITICAL,
    "asyncio": logging.CRITICAL,
    "bokeh": logging.ERROR,
    "fsspec": logging.WARNING,
    "matplotlib": logging.WARNING,
    "PIL": logging.WARNING,
}


def quiet_libraries(verbose: bool = False) -> None:
    """Raise the loggers of :data:`QUIET_LEVELS` (and each of their descendants that has a
    level of its own) to at least their quiet level, unless ``verbose``; a logger already
    quieter stays so. Idempotent.

    Dask sets its loggers' levels when it is imported (``distributed`` INFO,
    ``distributed.client`` WARNING), so a call before that import is undone by it:
    glshade calls this again where it starts Dask (:mod:`glshade.measure.cluster`)."""
    if verbose:
        return
    loggers = logging.root.manager.loggerDict
    for name, level in QUIET_LEVELS.items():
        _raise_level(logging.getLogger(name), level)
        for child_name, child in list(loggers.items()):
            if (
                child_name.startswith(name + ".")
                and isinstance(child, logging.Logger)
                and child.level != logging.NOTSET
            ):
                _raise_level(child, level)


def _raise_level(logger: logging.Logger, level: int) -> None:
    if logger.level < level:
        logger.setLevel(level)


@contextlib.contextmanager
def silenced(logger_name: str) -> Iterator[None]:
    """Neither the named library's log records nor Python warnings reach stderr meanwhile
    (tifffile logs what it makes of a damaged file; glshade's error says it in one line)."""
    logger = logging.getLogger(logger_name)
    disabled, logger.disabled = logger.disabled, True
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        logger.disabled = disabled
