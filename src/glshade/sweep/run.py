"""Running a sweep: in this process, or on Dask (the executors of :mod:`glshade.measure`).

Both ways measure the same cases with the same engine (:mod:`glshade.measure.engine`) and
write through the same store (:mod:`glshade.sweep.store`), on this process only: workers
return rows, never files. The table is therefore the same whichever way a sweep ran
(``tests/test_sweep.py`` checks it), and a rerun computes only the cases without a case
file. The output directory is locked for the run (a second writer is refused).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from glshade.errors import GlshadeError
from glshade.measure.executors import Distribution, Row
from glshade.measure.locks import run_lock
from glshade.measure.where import open_executor
from glshade.sweep import store
from glshade.sweep.spec import MAX_CASES_UNCONFIRMED, GridPoint, SweepSpec


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
    with run_lock(out_dir, "glshade sweep"):
        store.prepare(out_dir, spec, overwrite)
        cases = spec.cases()
        records = {c.case_id: store.load_case(out_dir, c.case_id, spec.method) for c in cases}
        done = {key: record for key, record in records.items() if record is not None}
        pending = list({c.case_id: c for c in cases if c.case_id not in done}.values())
        start = time.perf_counter()
        bar = _progress_bar(len(records), len(done), progress)
        try:
            for row in _rows(spec, pending, distribution, renderer):
                case_id, record, image = row
                store.write_case(out_dir, case_id, record, image)
                done[case_id] = record
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
    spec: SweepSpec, pending: list[GridPoint], distribution: Distribution, renderer
) -> Iterator[Row]:
    if not pending:
        return
    with open_executor(distribution, renderer) as executor:
        yield from executor.rows([point.case for point in pending], spec.settings, spec.images)


def _progress_bar(total: int, initial: int, enabled: bool):
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, unit="case", desc="glshade sweep", dynamic_ncols=True)
