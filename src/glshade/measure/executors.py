"""Where cases are measured: in this process (:class:`LocalExecutor`) or on a Dask
cluster (:class:`glshade.measure.cluster.DaskExecutor`; :func:`glshade.measure.where.
open_executor` picks one). Both measure with the same
engine (:func:`glshade.measure.engine.measure_many`) and return the same rows, records
and never frames; the calling process alone writes files, so a table cannot depend on
where a case ran. An executor is a context manager with two methods:
``rows(cases, settings, images)`` (the records, for tables) and ``measured(cases,
settings, extra)`` (whole :class:`~glshade.measure.engine.Measured` results, ``extra`` run
where each case is measured: the study's thumbnails and overlays).
"""

from __future__ import annotations

import functools
from collections.abc import Iterator, Sequence
from concurrent.futures import Executor, ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Self

from glshade.errors import GlshadeError
from glshade.instruments.base import Case, Extra, Instrument, Measured
from glshade.instruments.record import Record
from glshade.instruments.registry import instrument_for
from glshade.measure.capacity import check_threads, check_worker_count
from glshade.measure.engine import measure_many

if TYPE_CHECKING:
    from glshade.rendering import Renderer

#: What every executor yields per case: its key, its record, its image as PNG bytes (when
#: images were asked for: the paper metric's best phase, phase measuring's first recorded
#: frame) or None.
Row = tuple[Any, Record, bytes | None]


@dataclass(frozen=True)
class Distribution:
    """Where the cases run: ``workers`` local Dask worker processes, or the cluster at
    ``scheduler``; neither: this process (``threads`` for the analysis). ``batch``: most
    cases per Dask task; ``connect_timeout_s``: the most seconds joining ``scheduler`` may
    take (:mod:`glshade.measure.scheduler`). ``verbose``: Dask's own log lines are shown
    (:func:`glshade.logs.quiet_libraries`; the CLI's ``--verbose``).

    ``workers`` and ``threads`` are bounded by this machine's cores and memory budget
    (:mod:`glshade.measure.capacity`; checked again, at the size of the frames, before
    cases are sent to the workers)."""

    workers: int | None = None
    scheduler: str | None = None
    threads: int = 2
    connect_timeout_s: float = 10.0
    batch: int = 16
    verbose: bool = False

    def __post_init__(self) -> None:
        if self.workers is not None and self.scheduler is not None:
            raise GlshadeError(
                "--workers and --scheduler: give one of them (local workers, or an existing "
                "cluster)"
            )
        if self.workers is not None and not 1 <= self.workers <= 256:
            raise GlshadeError(f"--workers: must be an integer in [1, 256], got {self.workers}")
        if self.workers is not None:
            check_worker_count(self.workers)
        check_threads(self.threads)
        if not 0 < self.connect_timeout_s <= 600:
            raise GlshadeError(
                f"--connect-timeout: must be in (0, 600] seconds, got {self.connect_timeout_s:g}"
            )
        if not 1 <= self.batch <= 4096:
            raise GlshadeError(f"--batch: must be an integer in [1, 4096], got {self.batch}")

    @property
    def on_dask(self) -> bool:
        return self.workers is not None or self.scheduler is not None


class LocalExecutor:
    """Measures cases in this process: one renderer (made on first use unless given),
    ``threads`` analysis threads."""

    def __init__(self, threads: int = 2, renderer: Renderer | None = None) -> None:
        self.threads, self.renderer, self._owns = threads, renderer, renderer is None

    def rows(self, cases: Sequence[Case], settings: Any, images: bool) -> Iterator[Row]:
        with ThreadPoolExecutor(max_workers=self.threads) as pool:
            yield from measure_rows(self._renderer(), cases, settings, images, pool)

    def measured(
        self, cases: Sequence[Case], settings: Any, extra: Extra | None
    ) -> Iterator[Measured]:
        """Every case measured, in the engine's order (the GL work on this thread)."""
        with ThreadPoolExecutor(max_workers=self.threads) as pool:
            yield from measure_many(self._renderer(), cases, settings, pool=pool, extra=extra)

    def _renderer(self) -> Renderer:
        if self.renderer is None:
            from glshade.gpu.renderer import Renderer as GlRenderer

            self.renderer = GlRenderer()
        return self.renderer

    def close(self) -> None:
        if self._owns and self.renderer is not None:
            self.renderer.release()
            self.renderer = None

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def measure_rows(
    renderer: Renderer,
    cases: Sequence[Case],
    settings: Any,
    images: bool,
    pool: Executor | None = None,
) -> Iterator[Row]:
    """The engine's results as rows: what a worker returns, what the caller writes."""
    extra = functools.partial(_best_image_png, instrument_for(settings)) if images else None
    for measured in measure_many(renderer, cases, settings, pool=pool, extra=extra):
        yield measured.case.key, measured.record, measured.extra


def _best_image_png(chosen: Instrument, case: Case, result: Any, view: Any) -> bytes | None:
    """The case's picture as its instrument's camera records it (the paper metric's image
    at its best phase; phase measuring's first recorded frame), as PNG."""
    from glshade.files import encode_png

    image = chosen.image(case, result, view)
    return None if image is None else encode_png(image, bits=8)
