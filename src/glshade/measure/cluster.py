"""A sweep on Dask (``dask.distributed``): local worker processes or an existing cluster.

- ``--workers N`` starts a :class:`distributed.LocalCluster` of N single-threaded worker
  processes; ``--scheduler ADDRESS`` joins an existing cluster (dask-jobqueue on SLURM,
  dask-cuda's ``LocalCUDACluster`` with one worker per GPU, ...). A scheduler that does not
  answer within ``connect_timeout_s`` is one clear error.
- Each worker holds one EGL context and renderer for its lifetime
  (:class:`RendererPlugin`, a worker plugin), on the EGL device of its CUDA GPU
  (:func:`glshade.gpu.egl_cuda.worker_egl_device`).
- A task is a batch of cases of one geometry (hence one shader feature set), in the
  engine's order: its defect-free analysis is made once per batch, its program compiled
  once per worker. A task returns rows (numbers; PNG bytes only when images were asked
  for), never frames; this process writes them.
- A worker that dies mid-task: the scheduler runs its task again on another worker (Dask
  allows ``distributed.scheduler.allowed-failures`` deaths per task, 3 by default). Its
  cases are measured again from scratch and written once, by id, when the task finishes;
  a case finished before the death is on disk already and skipped by a rerun.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from typing import Self, cast

from distributed import Client, LocalCluster, as_completed, get_worker
from distributed.client import FutureCancelledError
from distributed.diagnostics.plugin import WorkerPlugin
from distributed.scheduler import KilledWorker

from glshade.errors import GlshadeError
from glshade.gpu.context import GLContext
from glshade.gpu.renderer import Renderer
from glshade.measure.engine import Case, Extra, Measured, grouped, measure_many
from glshade.measure.executors import Distribution, Row, measure_rows

PLUGIN_NAME = "glshade-renderer"


class RendererPlugin(WorkerPlugin):
    """Worker plugin: one GL context and renderer per worker process, made on the
    worker's first task (in the task thread) and released when the worker closes."""

    name = PLUGIN_NAME

    def __init__(self) -> None:
        self.context: GLContext | None = None
        self.renderer: Renderer | None = None
        self.device: int | None = None

    def setup(self, worker) -> None:
        from glshade.gpu.egl_cuda import worker_egl_device
        from glshade.process import reuse_freed_memory

        self.device = worker_egl_device()
        reuse_freed_memory()  # the worker process measures many cases, as `glshade paper` does

    def get(self) -> Renderer:
        """The worker's renderer (made on first use)."""
        if self.renderer is None:
            self.context = GLContext(device_index=self.device)
            self.renderer = Renderer(self.context)
        return self.renderer

    def teardown(self, worker) -> None:
        if self.renderer is not None:
            self.renderer.release()
        if self.context is not None:
            self.context.release()
        self.context = self.renderer = None


def measure_batch(cases: list[Case], settings, images: bool) -> list[Row]:
    """A Dask task: measure one batch with the worker's renderer; returns its rows."""
    return list(measure_rows(_worker_renderer(), cases, settings, images))


def measure_whole(cases: list[Case], settings, extra: Extra | None) -> list[Measured]:
    """A Dask task: measure one batch with the worker's renderer; returns its results
    whole, with what ``extra`` made of each (the worker traces and analyses in turn)."""
    return list(measure_many(_worker_renderer(), cases, settings, extra=extra))


def _worker_renderer() -> Renderer:
    plugin = cast(RendererPlugin, get_worker().plugins[PLUGIN_NAME])
    return plugin.get()


def batches(cases: list[Case], size: int, settings=None) -> list[list[Case]]:
    """The tasks: the engine's geometry groups (for ``settings``), each cut into pieces of
    at most ``size``."""
    out = []
    for group in grouped(cases, settings):
        out += [group[i : i + size] for i in range(0, len(group), size)]
    return out


def connect(scheduler: str | None, workers: int | None, timeout_s: float):
    """A :class:`distributed.Client` (and the LocalCluster it owns, or None)."""
    if scheduler is not None:
        try:
            return Client(scheduler, timeout=f"{timeout_s}s", set_as_default=False), None
        except (OSError, TimeoutError, ValueError) as exc:
            reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            raise GlshadeError(
                f"--scheduler {scheduler}: no Dask scheduler answered within {timeout_s:g} s "
                f"({reason[:160]})"
            ) from None
    cluster = LocalCluster(
        n_workers=workers,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
        silence_logs=logging.ERROR,
    )
    return Client(cluster, set_as_default=False), cluster


class DaskExecutor:
    """Measures cases on a Dask cluster; a context manager that holds the client (and the
    LocalCluster it started) across calls, so the optimiser pays the start-up once."""

    def __init__(self, distribution: Distribution) -> None:
        self.distribution = distribution
        self.client, self.cluster = connect(
            distribution.scheduler, distribution.workers, distribution.connect_timeout_s
        )
        try:
            self.client.register_plugin(RendererPlugin(), name=PLUGIN_NAME)
        except BaseException:
            self.close()
            raise
        self._submitted = 0

    def rows(self, cases: list[Case], settings, images: bool) -> Iterator[Row]:
        """Rows of ``cases``, as their batches finish (any order)."""
        for rows in self._run(measure_batch, cases, settings, images):
            yield from rows

    def measured(self, cases: list[Case], settings, extra: Extra | None) -> Iterator[Measured]:
        """Whole results of ``cases`` (``extra`` run on the workers), as their batches
        finish (any order)."""
        for results in self._run(measure_whole, cases, settings, extra):
            yield from results

    def _run(self, task, cases: list[Case], settings, option) -> Iterator[list]:
        """``task(batch, settings, option)`` on the cluster for every batch, results as they
        finish."""
        futures = []
        for batch in batches(cases, self.distribution.batch, settings):
            self._submitted += 1
            futures.append(
                self.client.submit(
                    task,
                    batch,
                    settings,
                    option,
                    pure=False,
                    key=f"glshade-batch-{self._submitted}-{batch[0].key}",
                )
            )
        try:
            for future in as_completed(futures, loop=self.client.loop):
                yield future.result()
                future.release()
        except KilledWorker as exc:
            raise GlshadeError(
                f"a batch of cases killed its workers too often ({exc}); the finished cases are "
                "saved: rerun to resume"
            ) from None
        except FutureCancelledError:
            raise GlshadeError(
                "the Dask cluster cancelled the sweep's tasks; finished cases are saved: rerun to "
                "resume"
            ) from None

    def close(self) -> None:
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
