"""Running a sweep: in this process, or on Dask (the executors of :mod:`glshade.measure`).

Both ways measure the same cases with the same engine (:mod:`glshade.measure.engine`) and
write through the same store (:mod:`glshade.sweep.store`), on this process only: workers
return rows, never files. The table is therefore the same whichever way a sweep ran
(``tests/test_sweep.py`` checks it), and a rerun computes only the cases without a case
file. The output directory is locked for the run (a second writer is refused).
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable, Iterator
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from glshade.measure.case_files import Rejected
from glshade.measure.executors import Distribution, Row
from glshade.measure.where import open_executor
from glshade.sweep import store
from glshade.sweep.spec import GridPoint, SweepSpec, check_grid
from glshade.sweep.store import CaseRecord
from glshade.sweep.table import TableWriter

if TYPE_CHECKING:
    from glshade.rendering import Renderer


@dataclass
class SweepResult:
    """What a run did: ``cases`` rows in the table (``statuses``: how many of each
    status), ``computed`` measured now, ``skipped`` found measured, in ``seconds``; the
    table itself is in ``out_dir`` (:attr:`rows` reads it back)."""

    cases: int
    statuses: dict[str, int]
    computed: int
    skipped: int
    seconds: float
    out_dir: Path

    @property
    def rows(self) -> list[dict[str, Any]]:
        """The table's rows, read back from ``results.parquet``."""
        return store.read_table(self.out_dir)


def check_size(spec: SweepSpec, yes: bool) -> None:
    """A grid beyond :data:`MAX_CASES_UNCONFIRMED` cases runs only when confirmed."""
    check_grid([len(axis.entries) for axis in spec.axes], spec.source, yes)


def run_sweep(
    spec: SweepSpec,
    out_dir: Path,
    distribution: Distribution = Distribution(),
    *,
    yes: bool = False,
    overwrite: bool = False,
    progress: bool = False,
    renderer: Renderer | None = None,
    on_row: Callable[[Row], None] | None = None,
    notify: Callable[[str], None] | None = None,
) -> SweepResult:
    """Run (or resume) ``spec`` into ``out_dir``; then write its table.

    The grid is walked chunk by chunk (:meth:`~glshade.sweep.spec.GridCases.chunks`): a
    chunk's cases are made, those with a case file are read back, the others measured and
    written, and the chunk's rows go to the table (:class:`~glshade.sweep.table.
    TableWriter`) before the next chunk is made. The first case is measured as soon as
    the first chunk is made, and memory holds one chunk, whatever the grid's size.

    ``renderer``: an existing one for the in-process path. ``on_row`` is called after each
    computed case is safely on disk (tests kill a run there). ``notify(line)`` is told of
    case files that fail their check (:mod:`glshade.measure.case_files`: they are measured
    again): at the first chunk that has any, and the rest once at the end (a warning when
    None)."""
    check_size(spec, yes)
    out_dir = Path(out_dir)
    with store.opened(out_dir, spec, overwrite):
        tally = _Tally(_progress_bar(spec.count, progress), notify)
        start = time.perf_counter()
        with TableWriter(out_dir, spec) as table, ExitStack() as stack:
            executor = None
            try:
                for chunk in spec.cases().chunks():
                    done = tally.found(chunk, out_dir, spec.method)
                    pending = list({c.case_id: c for c in chunk if c.case_id not in done}.values())
                    if pending and executor is None:  # opened once, on the first case to measure
                        executor = stack.enter_context(open_executor(distribution, renderer))
                    for row in _rows(spec, pending, executor):
                        case_id, record, image = row
                        store.write_case(out_dir, case_id, record, image)
                        done[case_id] = record
                        tally.measured(case_id)
                        if on_row is not None:
                            on_row(row)
                    table.add(tally.rows(spec, chunk, done))
            finally:
                tally.close()
                tally.rejected.say(notify)
            stack.close()  # the executor (a Dask cluster too) is done before the tables
            seconds = time.perf_counter() - start
            table.finish()
        return SweepResult(
            table.rows, dict(tally.statuses), tally.computed, tally.skipped, seconds, out_dir
        )


class _Tally:
    """The counts of a run (found, measured, each status in the table) and its bar."""

    def __init__(self, bar, notify: Callable[[str], None] | None = None) -> None:
        self.bar = bar
        self.notify = notify
        self.rejected = Rejected()  # case files not trusted, not yet said
        self.said_once = False
        self.computed = self.skipped = 0
        self.statuses: Counter[str] = Counter()
        self._points: Counter[str] = Counter()  # the chunk's points of each case id

    def found(self, chunk: list[GridPoint], out_dir: Path, method: str) -> dict[str, CaseRecord]:
        """The chunk's cases already measured (their case files), by id."""
        self._points = Counter(c.case_id for c in chunk)
        done = store.finished(out_dir, self._points, method, self.rejected)
        if self.rejected.found and not self.said_once:  # the first at once, the rest at the end
            self.rejected.say(self.notify)
            self.rejected, self.said_once = Rejected(), True
        self.skipped += len(done)
        self._advance(sum(self._points[key] for key in done))
        return done

    def measured(self, case_id: str) -> None:
        """One case of the chunk measured now (and on disk)."""
        self.computed += 1
        self._advance(self._points[case_id])

    def rows(
        self, spec: SweepSpec, chunk: list[GridPoint], done: dict[str, CaseRecord]
    ) -> list[dict[str, Any]]:
        """The chunk's rows of the table (:func:`glshade.sweep.store.table_rows`)."""
        rows = store.table_rows(spec, chunk, done)
        self.statuses.update(str(row.get("status", "ok")) for row in rows)
        return rows

    def _advance(self, cases: int) -> None:
        if self.bar is not None and cases:
            self.bar.update(cases)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _rows(spec: SweepSpec, pending: list[GridPoint], executor) -> Iterator[Row]:
    """The pending cases measured, those of one instrument setting together (a
    ``measure.KEY`` axis gives several)."""
    by_settings: dict[Any, list[GridPoint]] = {}
    for point in pending:
        by_settings.setdefault(point.settings or spec.settings, []).append(point)
    for settings, points in by_settings.items():
        yield from executor.rows([point.case for point in points], settings, spec.images)


def _progress_bar(total: int, enabled: bool):
    from glshade.progress import progress_bar

    return progress_bar(total, "glshade sweep", "case", enabled=enabled)
