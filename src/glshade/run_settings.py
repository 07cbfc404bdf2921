"""Where and how a command's cases run (:class:`RunSettings`): worker processes or an
existing Dask cluster, the analysis threads of a run in one process, the cases per Dask
task and the EGL device, each declared once with its default, range and short flag, as
the scene's parameters and the instruments' settings are. The command line's flags, their
help, their one-line errors and ``docs/measure-settings.md`` come from these
declarations; what a machine can hold (two threads per CPU core, the workers its memory
budget holds: :mod:`glshade.measure.capacity`) is checked when the run starts.
"""

from __future__ import annotations

from dataclasses import dataclass

from glshade.params import Table, param


@dataclass(frozen=True)
class RunSettings(Table):
    """A run's execution settings (``run.*``); unset values take the documented
    fallback."""

    table = "run"

    workers: int | str | None = param(
        "run.workers", "", None,
        "worker processes of a local Dask cluster, each tracing and measuring whole "
        "geometries with its own renderer (unset: this process; at most 2 per CPU core and "
        "as many as the memory budget GLSHADE_MEMORY_BUDGET_MB holds)",
        value_type="integer", lo=0, hi=256, closed=True, flag="--workers",
    )  # fmt: skip
    scheduler: str | None = param(
        "run.scheduler", "", None,
        "an existing Dask cluster's scheduler address, e.g. tcp://head:8786 (dask-jobqueue, "
        "dask-cuda, ...)",
        value_type="text", flag="--scheduler",
    )  # fmt: skip
    connect_timeout: float = param(
        "run.connect_timeout", "s", 10.0, "seconds joining run.scheduler may take",
        lo=0.0, hi=3600.0, closed=True, nonzero=True, allowed_text="in (0, 3600] s",
        flag="--connect-timeout",
    )  # fmt: skip
    threads: int = param(
        "run.threads", "", 2,
        "in this process: threads for the instrument's analysis while this thread traces "
        "(at most 2 per CPU core)",
        value_type="integer", lo=1, hi=512, closed=True, flag="--threads",
    )  # fmt: skip
    batch: int = param(
        "run.batch", "", 16, "Dask: the most cases one task measures",
        value_type="integer", lo=1, hi=4096, closed=True, flag="--batch",
    )  # fmt: skip
    device: int | None = param(
        "run.device", "", None,
        "EGL device index in this process (unset: GLSHADE_EGL_DEVICE or 0)",
        value_type="integer", lo=0, hi=1024, closed=True, flag="--device",
    )  # fmt: skip
