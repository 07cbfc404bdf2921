"""A sweep on Dask (``dask.distributed``): local worker processes or an existing cluster.

- ``--workers N`` starts a :class:`distributed.LocalCluster` of N single-threaded worker
  processes; ``--scheduler ADDRESS`` joins an existing cluster (dask-jobqueue on SLURM,
  dask-cuda's ``LocalCUDACluster`` with one worker per GPU, ...). Joining finishes within
  ``connect_timeout_s`` or is one clear error (:mod:`glshade.measure.scheduler`).
- Local workers are bounded by the cores and the memory budget
  (:mod:`glshade.measure.capacity`): when the distribution is made, and again, at the
  size of their frames, before any case is sent to them.
- Dask's own log lines are quietened (:func:`glshade.logs.quiet_libraries`) unless the
  distribution is verbose: in this process, and in the local worker processes (their
  plugin does it there); an existing cluster's workers are left as they are.
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
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING, Any, Self, cast

from distributed import Client, LocalCluster, as_completed, get_worker
from distributed.client import FutureCancelledError
from distributed.diagnostics.plugin import WorkerPlugin
from distributed.scheduler import KilledWorker

from glshade.errors import GlshadeError
from glshade.gpu.context import GLContext
from glshade.gpu.renderer import Renderer
from glshade.instruments.base import Case, Extra, Measured
from glshade.instruments.registry import instrument_for
from glshade.logs import quiet_libraries
from glshade.measure.capacity import check_worker_count
from glshade.measure.engine import grouped, measure_many
from glshade.measure.executors import Distribution, Row, measure_rows
from glshade.measure.scheduler import join_scheduler

if TYPE_CHECKING:
    from distributed import Worker


PLUGIN_NAME = "glshade-renderer"


class RendererPlugin(WorkerPlugin):
    """Worker plugin: one GL context and renderer per worker process, made on the
    worker's first task (in the task thread) and released when the worker closes."""

    name = PLUGIN_NAME

    def __init__(self, quiet: bool = False) -> None:
        self.context: GLContext | None = None
        self.renderer: Renderer | None = None
        self.device: int | None = None
        self.quiet = quiet  # quieten Dask's loggers in the worker process (glshade's own)

    def setup(self, worker: Worker) -> None:
        from glshade.gpu.egl_cuda import worker_egl_device
        from glshade.process import reuse_freed_memory

        if self.quiet:  # its shut-down's CommClosedError tracebacks, printed on our stderr
            quiet_libraries()
        self.device = worker_egl_device()
        reuse_freed_memory()  # the worker process measures many cases, as `glshade paper` does

    def get(self) -> Renderer:
        """The worker's renderer (made on first use)."""
        if self.renderer is None:
            self.context = GLContext(device_index=self.device)
            self.renderer = Renderer(self.context)
        return self.renderer

    def teardown(self, worker: Worker) -> None:
        if self.renderer is not None:
            self.renderer.release()
        if self.context is not None:
            self.context.release()
        self.context = self.renderer = None


def measure_batch(cases: list[Case], settings: Any, images: bool) -> list[Row]:
    """A Dask task: measure one batch with the worker's renderer; returns its rows."""
    return list(measure_rows(_worker_renderer(), cases, settings, images))


def measure_whole(cases: list[Case], settings: Any, extra: Extra | None) -> list[Measured]:
    """A Dask task: measure one batch with the worker's renderer; returns its results
    whole, with what ``extra`` made of each (the worker traces and analyses in turn)."""
    return list(measure_many(_worker_renderer(), cases, settings, extra=extra))


def _worker_renderer() -> Renderer:
    plugin = cast(RendererPlugin, get_worker().plugins[PLUGIN_NAME])
    return plugin.get()


def batches(cases: list[Case], size: int, settings: Any) -> list[list[Case]]:
    """The tasks: the engine's geometry groups (for ``settings``), each cut into pieces of
    at most ``size``."""
    out = []
    for group in grouped(cases, settings):
        out += [group[i : i + size] for i in range(0, len(group), size)]
    return out


def start_local(workers: int, verbose: bool) -> tuple[Client, LocalCluster]:
    """A LocalCluster of ``workers`` single-threaded worker processes (no dashboard; its
    and its workers' log lines quietened unless ``verbose``) and a client of it with the
    renderer plugin registered."""
    cluster = LocalCluster(
        n_workers=workers,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
        # no dashboard, but Dask's scheduler serves its health routes over HTTP anyway, on
        # port 8787 unless told: any free port of the loopback instead (no "Port 8787 is
        # already in use" warning where another cluster or notebook has it)
        scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
        silence_logs=logging.WARNING if verbose else logging.CRITICAL,
    )
    try:
        client = Client(cluster, set_as_default=False)
    except BaseException:
        cluster.close()
        raise
    try:
        client.register_plugin(RendererPlugin(quiet=not verbose), name=PLUGIN_NAME)
    except BaseException:
        _close(client, cluster)
        raise
    return client, cluster


def _close(client: Client, cluster: LocalCluster | None) -> None:
    """The client, then the cluster it owns (Dask's order: the client first, so it is
    not left waiting on a scheduler that has gone). A worker's heartbeat that still meets
    the closed scheduler (seen with 8 workers on 2 busy cores) is a ``CommClosedError``
    logged in the worker process: the plugin's :func:`~glshade.logs.quiet_libraries`
    keeps it off the terminal."""
    try:
        client.close()
    finally:
        if cluster is not None:
            cluster.close()


def frame_pixels(cases: list[Case]) -> int:
    """The largest frame of ``cases``, in pixels."""
    return max(case.scene.camera.width * case.scene.camera.height for case in cases)


class DaskExecutor:
    """Measures cases on a Dask cluster; a context manager that holds the client (and the
    LocalCluster it started) across calls, so the optimiser pays the start-up once."""

    def __init__(self, distribution: Distribution) -> None:
        self.distribution = distribution
        self.cluster: LocalCluster | None = None
        self._submitted = 0
        quiet_libraries(distribution.verbose)
        if distribution.scheduler is not None:
            self.client = join_scheduler(
                distribution.scheduler,
                distribution.connect_timeout_s,
                RendererPlugin(),
                PLUGIN_NAME,
            )
        else:
            assert distribution.workers is not None
            self.client, self.cluster = start_local(distribution.workers, distribution.verbose)

    def _check_memory(self, cases: list[Case], settings: Any) -> None:
        """Local workers fit the memory budget at the size of these cases' frames
        (:func:`glshade.measure.capacity.check_worker_count`); an existing cluster's
        machines are its own business."""
        if self.cluster is not None and self.distribution.workers is not None:
            method = instrument_for(settings).name
            check_worker_count(self.distribution.workers, frame_pixels(cases), method)

    def rows(self, cases: list[Case], settings: Any, images: bool) -> Iterator[Row]:
        """Rows of ``cases``, as their batches finish (any order)."""
        for rows in self._run(measure_batch, cases, settings, images):
            yield from rows

    def measured(self, cases: list[Case], settings: Any, extra: Extra | None) -> Iterator[Measured]:
        """Whole results of ``cases`` (``extra`` run on the workers), as their batches
        finish (any order)."""
        for results in self._run(measure_whole, cases, settings, extra):
            yield from results

    def _run(
        self,
        task: Callable[[list[Case], Any, Any], list[Any]],
        cases: list[Case],
        settings: Any,
        option: Any,
    ) -> Iterator[list]:
        """``task(batch, settings, option)`` on the cluster for every batch, results as they
        finish."""
        if not cases:
            return
        self._check_memory(cases, settings)
        client = self.client
        futures = []
        for batch in batches(cases, self.distribution.batch, settings):
            self._submitted += 1
            futures.append(
                client.submit(
                    task,
                    batch,
                    settings,
                    option,
                    pure=False,
                    key=f"glshade-batch-{self._submitted}-{batch[0].key}",
                )
            )
        try:
            for future in as_completed(futures, loop=client.loop):
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
        _close(self.client, self.cluster)

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
