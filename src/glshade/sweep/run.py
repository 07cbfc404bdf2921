"""Running a sweep: in this process, or on Dask (:mod:`glshade.sweep.distributed`).

Both ways measure the same cases with the same engine (:mod:`glshade.sweep.engine`) and
write through the same store (:mod:`glshade.sweep.store`), on this process only: workers
return rows, never files. The table is therefore the same whichever way a sweep ran
(``tests/test_sweep.py`` checks it), and a rerun computes only the cases without a case
file. The output directory is locked for the run (a second writer is refused).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Self

from glshade.errors import GlshadeError
from glshade.study.store import study_lock
from glshade.sweep import store
from glshade.sweep.spec import MAX_CASES_UNCONFIRMED, SweepCase, SweepSpec

#: What every path returns per case: ``(case_id, outputs, seconds, image PNG or None)``.
Row = tuple[str, dict[str, Any], dict[str, float], bytes | None]


@dataclass(frozen=True)
class Distribution:
    """Where the cases run: ``workers`` local Dask worker processes, or the cluster at
    ``scheduler``; neither: this process (``threads`` for the analysis)."""

    workers: int | None = None
    scheduler: str | None = None
    threads: int = 2
    connect_timeout_s: float = 10.0
    batch: int = 16

    def __post_init__(self) -> None:
        if self.workers is not None and self.scheduler is not None:
            raise GlshadeError(
                "--workers and --scheduler: give one of them (local workers, or an existing cluster)"
            )
        if self.workers is not None and not 1 <= self.workers <= 256:
            raise GlshadeError(f"--workers: must be an integer in [1, 256], got {self.workers}")
        if self.threads < 1:
            raise GlshadeError(f"--threads: must be an integer >= 1, got {self.threads}")
        if not 0 < self.connect_timeout_s <= 600:
            raise GlshadeError(
                f"--connect-timeout: must be in (0, 600] seconds, got {self.connect_timeout_s:g}"
            )
        if not 1 <= self.batch <= 4096:
            raise GlshadeError(f"--batch: must be an integer in [1, 4096], got {self.batch}")

    @property
    def on_dask(self) -> bool:
        return self.workers is not None or self.scheduler is not None


@dataclass
class SweepResult:
    rows: list[dict[str, Any]]
    computed: int
    skipped: int
    seconds: float
    out_dir: Path


def check_size(spec: SweepSpec, yes: bool) -> None:
    """A grid beyond :data:`MAX_CASES_UNCONFIRMED` cases runs only when confirmed."""
    if spec.count > MAX_CASES_UNCONFIRMED and not yes:
        raise GlshadeError(
            f"{spec.source}: the grid has {spec.count} cases (more than {MAX_CASES_UNCONFIRMED}); "
            "add --yes to run it"
        )


def run_sweep(
    spec: SweepSpec,
    out_dir: Path,
    distribution: Distribution = Distribution(),
    *,
    yes: bool = False,
    overwrite: bool = False,
    progress: bool = False,
    renderer=None,
    on_row: Callable[[Row], None] | None = None,
) -> SweepResult:
    """Run (or resume) ``spec`` into ``out_dir``; returns the table's rows.

    ``renderer``: an existing one for the in-process path. ``on_row`` is called after each
    computed case is safely on disk (tests kill a run there)."""
    check_size(spec, yes)
    out_dir = Path(out_dir)
    with study_lock(out_dir, "glshade sweep"):
        store.prepare(out_dir, spec, overwrite)
        cases = spec.cases()
        records = {c.case_id: store.load_case(out_dir, c.case_id) for c in cases}
        done = {key: record for key, record in records.items() if record is not None}
        pending = list({c.case_id: c for c in cases if c.case_id not in done}.values())
        start = time.perf_counter()
        bar = _progress_bar(len(records), len(done), progress)
        try:
            for row in _rows(spec, pending, distribution, renderer):
                case_id, outputs, seconds, image = row
                store.write_case(out_dir, case_id, outputs, seconds, image)
                done[case_id] = {"case_id": case_id, "outputs": outputs, "seconds": seconds}
                if bar is not None:
                    bar.update(1)
                if on_row is not None:
                    on_row(row)
        finally:
            if bar is not None:
                bar.close()
        rows = store.table_rows(spec, cases, done)
        store.write_tables(out_dir, spec, rows)
        return SweepResult(
            rows, len(pending), len(records) - len(pending), time.perf_counter() - start, out_dir
        )


def _rows(
    spec: SweepSpec, pending: list[SweepCase], distribution: Distribution, renderer
) -> Iterator[Row]:
    if not pending:
        return
    with open_executor(distribution, renderer) as executor:
        yield from executor.rows(pending, spec.settings, spec.images)


def open_executor(distribution: Distribution, renderer=None):
    """Where cases are measured: a :class:`LocalExecutor` or a Dask one
    (:class:`glshade.sweep.distributed.DaskExecutor`); a context manager either way."""
    if distribution.on_dask:
        from glshade.sweep.distributed import DaskExecutor

        return DaskExecutor(distribution)
    return LocalExecutor(distribution.threads, renderer)


class LocalExecutor:
    """Measures cases in this process: one renderer (made on first use unless given),
    ``threads`` analysis threads."""

    def __init__(self, threads: int = 2, renderer=None) -> None:
        self.threads, self.renderer, self._owns = threads, renderer, renderer is None

    def rows(self, cases: list[SweepCase], settings, images: bool) -> Iterator[Row]:
        if self.renderer is None:
            from glshade.gpu.renderer import Renderer

            self.renderer = Renderer()
        with ThreadPoolExecutor(max_workers=self.threads) as pool:
            yield from measure_rows(
                self.renderer, [(c.case_id, c.scene) for c in cases], settings, images, pool
            )

    def close(self) -> None:
        if self._owns and self.renderer is not None:
            self.renderer.release()
            self.renderer = None

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def measure_rows(renderer, items, settings, images: bool, pool=None) -> Iterator[Row]:
    """The engine's results as rows: what a worker returns, what this process writes."""
    from glshade.sweep.engine import measure_many

    extra = _best_image_png if images else None
    for measured in measure_many(renderer, items, settings, pool=pool, extra=extra):
        spent = measured.result.seconds
        seconds = {
            "trace_s": round(measured.trace_s, 4),
            "shade_s": round(spent.shade, 4),
            "contours_s": round(spent.contours, 4),
            "continuous_s": round(spent.continuous, 4),
        }
        yield (
            measured.token,
            store.case_outputs(measured.scene, measured.result),
            seconds,
            measured.extra,
        )


def _best_image_png(token, scene, result, view) -> bytes:
    from glshade.files import encode_png

    return encode_png(view.best_image(scene, result), bits=8)


def _progress_bar(total: int, initial: int, enabled: bool):
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, unit="case", desc="glshade sweep", dynamic_ncols=True)
