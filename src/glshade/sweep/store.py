"""What a sweep writes and reads back (docs/sweeps.md): one JSON file per finished case, keyed by
its id; ``results.parquet`` (one row per case of the grid: every swept key, every output)
and ``results.csv`` beside it; ``images/<id>.png`` on request; ``sweep.json``, the
manifest that ties the directory to one base scene, size, instrument (the paper's stripe
metric or phase measuring), its settings and glshade version. The columns and the records
are the instrument's: :class:`~glshade.instruments.record.Measurement` for the paper's metric,
:class:`~glshade.instruments.record.PmdMeasurement` for phase measuring. The directory, its
manifest and its case files are kept by the one store of every run
(:mod:`glshade.measure.store`, in the layout :data:`SWEEP`).

A case file is written atomically once its case is done (the mark a rerun looks for), so
a killed run loses only the cases in flight and a rerun computes each missing case once.
The tables are rebuilt from the case files at the end of every run. No GL here.
"""

from __future__ import annotations

import functools
import json
import os
from collections.abc import Iterable, Mapping
from contextlib import AbstractContextManager
from pathlib import Path
from typing import Any

from glshade.files import open_regular
from glshade.instruments.record import Column, Record
from glshade.measure import store
from glshade.measure.case_files import Rejected
from glshade.sweep.spec import GridPoint, SweepSpec

#: A case's record: its instrument's (the paper metric's, phase measuring's, a plug-in's).
CaseRecord = Record


def outputs(method: str) -> tuple[Column, ...]:
    """The output columns of an instrument's sweep table: its record's columns it keeps."""
    from glshade.instruments.registry import instrument

    chosen = instrument(method)
    return tuple(c for c in chosen.record_type.columns() if c.name in chosen.outputs)


def output_names(method: str) -> tuple[str, ...]:
    return tuple(c.name for c in outputs(method))


MANIFEST = "sweep.json"
PARQUET = "results.parquet"
CSV = "results.csv"


# --------------------------------------------------------------------------- directory
def _another_sweep(stored: dict, wanted: dict) -> str:
    """What a directory of another sweep holds, in a refusal: how the two differ."""
    names = {
        "glshade_version": "another glshade version",
        "method": "another method",
        "metric_version": "another metric version",
        "pmd_version": "another phase-measuring version",
        "base_scene": "another base scene",
        "size": "another size",
        "metric": "other metric settings",
    }
    differing = store.changed(stored, wanted, names)
    if "method" in differing:  # another instrument: its version and settings differ with it
        differing = [key for key in differing if key not in ("metric_version", "pmd_version")]
        differing = [key for key in differing if key != "metric"]
    if not differing:
        return "a sweep of unknown origin (no readable manifest)"
    first = differing[0]
    parts = [names[key] for key in differing]
    if first in ("glshade_version", "method", "size", "metric_version", "pmd_version"):
        parts[0] += f" ({stored.get(first)} there, {wanted.get(first)} here)"
    return "a sweep of " + ", ".join(parts)


def _as_now(out_dir: Path, stored: store.Stored) -> store.Stored:
    """The directory's manifest as this glshade writes it: a results table without one
    speaks for itself (its Parquet metadata); one written before the instrument was
    recorded measured with the paper's metric."""
    if stored is None and (out_dir / PARQUET).exists():
        stored = table_manifest(out_dir / PARQUET)
    if stored and "method" not in stored:
        stored = {**stored, "method": "paper"}
    return stored


def table_manifest(path: Path) -> dict:
    """The manifest a results table was written with ({} when it has none)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    with os.fdopen(open_regular(path, "--out"), "rb") as fh:  # never a FIFO read
        try:
            metadata = pq.read_schema(fh).metadata or {}
            return json.loads(metadata.get(b"glshade", b"{}"))
        except (OSError, ValueError, RecursionError, pa.ArrowException):
            return {}


#: A sweep's files: its manifest, its case files in ``cases/``, their images in
#: ``images/``, and its tables (what ``--overwrite`` removes, with the case files: never
#: anything else). Its case files are never reused by another sweep.
SWEEP = store.Layout(
    manifest=MANIFEST,
    held=_another_sweep,
    resume="the same sweep",
    images="images",
    files=(PARQUET, CSV),
    command="glshade sweep",
    as_now=_as_now,
)


def opened(
    out_dir: Path, spec: SweepSpec, overwrite: bool = False
) -> AbstractContextManager[list[Path]]:
    """``out_dir`` held for the run and tied to ``spec`` (its manifest written) for the
    ``with`` block, or refused: a directory holding a sweep of another base scene, size,
    metric or glshade version is never mixed into and never overwritten unless
    ``overwrite`` (which removes that sweep's files first)."""
    return store.opened(out_dir, SWEEP, spec.manifest(), overwrite, images=spec.images)


# --------------------------------------------------------------------------- case files
def write_case(
    out_dir: Path, case_id: str, record: CaseRecord, image_png: bytes | None = None
) -> None:
    """A finished case on disk: its image first, its JSON last (the "done" mark)."""
    data = {"outputs": record.outputs(), "seconds": record.seconds()}
    store.write_case(out_dir, SWEEP, case_id, data, image_png)


def finished(
    out_dir: Path, case_ids: Iterable[str], method: str = "paper", rejected: Rejected | None = None
) -> dict[str, CaseRecord]:
    """The finished cases among ``case_ids``: their records (the ``method``'s record type,
    its timings included) by id. A case file not to be trusted (a failed checksum,
    another case's id, an older or interrupted writer, another instrument's outputs, a
    value outside its column's type, range or words:
    :meth:`~glshade.instruments.record.Record.json_problem`) is left out, and ``rejected``
    collects it with the reason: measure it again."""
    read = functools.partial(_record, method)
    return store.load_cases(out_dir, SWEEP, case_ids, read, rejected)


def _record(method: str, data: dict, case_id: str) -> tuple[CaseRecord | None, str | None]:
    """A checked case file's record of ``method``, or why it is none."""
    found = data.get("outputs")
    if not isinstance(found, dict) or set(found) != set(output_names(method)):
        return None, f"does not hold the outputs of --method {method}"
    seconds = data.get("seconds")
    row = {**(seconds if isinstance(seconds, dict) else {}), **found}
    from glshade.instruments.registry import instrument

    kind = instrument(method).record_type
    problem = kind.json_problem(row)
    if problem is not None:
        return None, problem
    try:
        return kind.from_row(row), None
    except (KeyError, TypeError, ValueError) as exc:
        return None, f"does not read as a case ({str(exc)[:80]})"


# --------------------------------------------------------------------------- tables
def table_rows(
    spec: SweepSpec, cases: list[GridPoint], records: Mapping[str, CaseRecord]
) -> list[dict[str, Any]]:
    """One row per case of the grid that has a record: its id, swept columns, outputs."""
    rows = []
    for case in cases:
        record = records.get(case.case_id)
        if record is not None:
            rows.append({"case_id": case.case_id, **spec.swept_values(case), **record.outputs()})
    return rows


def read_table(out_dir: Path) -> list[dict[str, Any]]:
    """``results.parquet`` back as a list of rows."""
    import pyarrow.parquet as pq

    with os.fdopen(open_regular(Path(out_dir) / PARQUET, "results table"), "rb") as fh:
        return pq.read_table(fh).to_pylist()
