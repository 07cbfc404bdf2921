"""What a sweep writes and reads back (docs/sweeps.md): one JSON file per finished case, keyed by
its id; ``results.parquet`` (one row per case of the grid: every swept key, every output)
and ``results.csv`` beside it; ``images/<id>.png`` on request; ``sweep.json``, the
manifest that ties the directory to one base scene, size, instrument (the paper's stripe
metric or phase measuring), its settings and glshade version. The columns and the records
are the instrument's: :class:`~glshade.instruments.record.Measurement` for the paper's metric,
:class:`~glshade.instruments.record.PmdMeasurement` for phase measuring.

A case file is written atomically once its case is done (the mark a rerun looks for), so
a killed run loses only the cases in flight and a rerun computes each missing case once.
The tables are rebuilt from the case files at the end of every run. No GL here.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from glshade.errors import GlshadeError
from glshade.files import (
    atomic_write_bytes,
    make_inside,
    open_regular,
    read_regular,
    remove_inside,
)
from glshade.instruments.record import (
    COLUMNS,
    OUTPUT_NAMES,
    PMD_COLUMNS,
    PMD_OUTPUT_NAMES,
    Column,
    Measurement,
    PmdMeasurement,
)
from glshade.measure.case_files import Rejected, case_file_bytes, read_case_file
from glshade.sweep.spec import GridPoint, SweepSpec

#: A case's record: the paper metric's or phase measuring's.
CaseRecord = Measurement | PmdMeasurement
#: Each instrument's record.
RECORDS: dict[str, type[Measurement] | type[PmdMeasurement]] = {
    "paper": Measurement,
    "pmd": PmdMeasurement,
}
#: The outputs of a case in the table: the record's measured and closed-form columns
#: (its timings stay in the case files); the paper metric's, and phase measuring's.
OUTPUTS = tuple(c for c in COLUMNS if c.name in OUTPUT_NAMES)
PMD_OUTPUTS = tuple(c for c in PMD_COLUMNS if c.name in PMD_OUTPUT_NAMES)


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
#: What ``--overwrite`` removes: exactly these, never anything else.
SWEEP_FILES = (PARQUET, CSV)


# --------------------------------------------------------------------------- case files
def case_path(out_dir: Path, case_id: str) -> Path:
    return Path(out_dir) / "cases" / f"{case_id}.json"


def write_case(
    out_dir: Path, case_id: str, record: CaseRecord, image_png: bytes | None = None
) -> None:
    """A finished case on disk: its image first, its JSON last (the "done" mark)."""
    if image_png is not None:
        atomic_write_bytes(
            Path(out_dir) / "images" / f"{case_id}.png", image_png, "--out", within=out_dir
        )
    data = json.loads(json.dumps({"outputs": record.outputs(), "seconds": record.seconds()}))
    atomic_write_bytes(
        case_path(out_dir, case_id), case_file_bytes(case_id, data), "--out", within=out_dir
    )


def load_case(
    out_dir: Path, case_id: str, method: str = "paper", rejected: Rejected | None = None
) -> CaseRecord | None:
    """A finished case's record (the ``method``'s record type, its timings included), or
    None: missing, or not to be trusted (a failed checksum, another case's id, an older
    or interrupted writer, another instrument's outputs, a value outside its column's type,
    range or words: :meth:`~glshade.instruments.record.Record.json_problem`),
    which ``rejected`` collects with the reason: measure it again."""
    path = case_path(out_dir, case_id)
    found = read_case_file(path, case_id)
    record, problem = None, found.problem
    if found.record is not None:
        record, problem = _record(found.record, method)
    if rejected is not None:
        rejected.add(path, problem)
    return record


def _record(data: dict, method: str) -> tuple[CaseRecord | None, str | None]:
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


# --------------------------------------------------------------------------- directory
def prepare(out_dir: Path, spec: SweepSpec, overwrite: bool = False) -> None:
    """Tie ``out_dir`` to ``spec`` (write its manifest), or refuse: a directory holding a
    sweep of another base scene, size, metric or glshade version is never mixed into and
    never overwritten unless ``overwrite`` (which removes that sweep's files first)."""
    out_dir = Path(out_dir)
    wanted = spec.manifest()
    stored = _stored_manifest(out_dir)
    if stored and "method" not in stored:  # written before the instrument was recorded
        stored = {**stored, "method": "paper"}
    if stored is not None and stored != wanted:
        if not overwrite:
            raise GlshadeError(
                f"--out {out_dir}: holds a sweep of {_difference(stored, wanted)}; rerun the same "
                "sweep "
                "to resume it, add --overwrite to replace it, or choose another --out"
            )
        _remove(out_dir)
    make_inside(out_dir, "cases")
    if spec.images:
        make_inside(out_dir, "images")
    atomic_write_bytes(
        out_dir / MANIFEST, json.dumps(wanted, indent=2).encode(), "--out", within=out_dir
    )


def _stored_manifest(out_dir: Path) -> dict | None:
    """The directory's manifest; a results table without one speaks for itself (its
    Parquet metadata); a directory of other files is no sweep (None)."""
    manifest = out_dir / MANIFEST
    if manifest.exists() or manifest.is_symlink():
        try:
            stored = json.loads(read_regular(manifest, "--out"))
        except (ValueError, RecursionError):
            return {}
        return stored if isinstance(stored, dict) else {}
    if (out_dir / PARQUET).exists():
        return table_manifest(out_dir / PARQUET)
    return None


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


def _difference(stored: dict, wanted: dict) -> str:
    names = {
        "glshade_version": "another glshade version",
        "method": "another method",
        "metric_version": "another metric version",
        "pmd_version": "another phase-measuring version",
        "base_scene": "another base scene",
        "size": "another size",
        "metric": "other metric settings",
    }
    differing = [key for key in names if stored.get(key) != wanted.get(key)]
    if "method" in differing:  # another instrument: its version and settings differ with it
        differing = [key for key in differing if key not in ("metric_version", "pmd_version")]
        differing = [key for key in differing if key != "metric"]
    if not differing:
        return "unknown origin (no readable manifest)"
    first = differing[0]
    parts = [names[key] for key in differing]
    if first in ("glshade_version", "method", "size", "metric_version", "pmd_version"):
        parts[0] += f" ({stored.get(first)} there, {wanted.get(first)} here)"
    return ", ".join(parts)


def _remove(out_dir: Path) -> None:
    doomed = [out_dir / name for name in (*SWEEP_FILES, MANIFEST)]
    doomed += sorted((out_dir / "cases").glob("*.json")) + sorted(
        (out_dir / "images").glob("*.png")
    )
    for path in doomed:
        remove_inside(out_dir, path)


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


def _cell(value: Any) -> Any:
    return list(value) if isinstance(value, tuple) else value


def _csv_cell(value: Any) -> Any:
    if isinstance(value, (list, tuple, dict)):
        return json.dumps(list(value) if isinstance(value, tuple) else value)
    return "" if value is None else value


def read_table(out_dir: Path) -> list[dict[str, Any]]:
    """``results.parquet`` back as a list of rows."""
    import pyarrow.parquet as pq

    with os.fdopen(open_regular(Path(out_dir) / PARQUET, "results table"), "rb") as fh:
        return pq.read_table(fh).to_pylist()
