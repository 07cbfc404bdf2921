"""How many local worker processes and analysis threads this machine holds: its CPU cores
and the memory budget (``GLSHADE_MEMORY_BUDGET_MB``, :func:`glshade.gpu.renderer.
memory_budget_from_env`).

- Cores: at most :data:`PER_CORE` worker processes (or analysis threads) per core this
  process may run on (its CPU affinity). A worker traces with the GL driver, which on
  llvmpipe spreads one draw over every core, then analyses on one core: two per core let
  one worker's analysis overlap another's trace; more only add processes and memory.
- Memory: the worker processes together stay within the budget, at the peak resident
  memory measured for one worker process of its instrument
  (:attr:`glshade.instruments.base.Instrument.worker_memory`).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from glshade.errors import GlshadeError
from glshade.instruments.registry import instrument

#: Worker processes (or analysis threads) allowed per CPU core.
PER_CORE = 2


def usable_cores() -> int:
    """CPU cores this process may run on (its affinity where the system has one)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


@dataclass(frozen=True)
class WorkerLimit:
    """The most local worker processes for frames of ``pixels`` pixels (0: not yet known)
    measured by ``method``: by the cores, and by the memory budget."""

    cores: int
    budget_mib: float
    worker_mib: float
    pixels: int
    method: str

    @property
    def by_cores(self) -> int:
        return self.cores * PER_CORE

    @property
    def by_memory(self) -> int:
        return int(self.budget_mib // self.worker_mib)

    @property
    def allowed(self) -> int:
        return min(self.by_cores, self.by_memory)

    def reason(self) -> str:
        """Why, in words: both bounds."""
        by = instrument(self.method).title
        frames = f" measuring {_frames(self.pixels)} by {by}" if self.pixels else ""
        return (
            f"{self.cores} CPU cores x {PER_CORE} = {self.by_cores}; the memory budget of "
            f"{self.budget_mib:.0f} MiB (GLSHADE_MEMORY_BUDGET_MB) / about "
            f"{self.worker_mib:.0f} MiB per worker{frames} = {self.by_memory}"
        )


def worker_limit(pixels: int = 0, method: str = "paper") -> WorkerLimit:
    """This machine's :class:`WorkerLimit` (the budget read from the environment)."""
    from glshade.budget import memory_budget_from_env

    memory = instrument(method).worker_memory
    return WorkerLimit(
        cores=usable_cores(),
        budget_mib=memory_budget_from_env() / (1 << 20),
        worker_mib=memory.mib(pixels),
        pixels=pixels,
        method=method,
    )


def check_worker_count(
    workers: int, pixels: int = 0, method: str = "paper", in_process: bool = False
) -> None:
    """Refuse more local worker processes than :func:`worker_limit` allows, in one line
    naming ``--workers``, the value, the allowed range and why. ``in_process``: the flag
    also takes ``auto`` and 0 (``glshade paper``)."""
    limit = worker_limit(pixels, method)
    if workers <= limit.allowed:
        return
    if limit.allowed < 1:
        raise GlshadeError(
            f"--workers {workers}: no worker process fits this machine ({limit.reason()}); "
            f"run in this process ({'--workers 0' if in_process else 'no --workers'}) or raise "
            "GLSHADE_MEMORY_BUDGET_MB"
        )
    lowest = "auto or an integer in [0" if in_process else "an integer in [1"
    smaller = (
        "; a smaller --size allows more"
        if limit.pixels and limit.by_memory < limit.by_cores
        else ""
    )
    raise GlshadeError(
        f"--workers: must be {lowest}, {limit.allowed}] on this machine ({limit.reason()}), "
        f"got {workers}{smaller}"
    )


def check_threads(threads: int) -> None:
    """The analysis threads of a run in one process: at least one, at most
    :data:`PER_CORE` per core."""
    if threads < 1:
        raise GlshadeError(f"--threads: must be an integer >= 1, got {threads}")
    most = usable_cores() * PER_CORE
    if threads > most:
        raise GlshadeError(
            f"--threads: must be an integer in [1, {most}] on this machine "
            f"({usable_cores()} CPU cores x {PER_CORE}), got {threads}"
        )


def _frames(pixels: int) -> str:
    side = round(pixels**0.5)
    return f"{side}² frames" if side * side == pixels else f"frames of {pixels} pixels"
