"""The sweep's tables written as its cases come (docs/sweeps.md): ``results.csv`` row by
row, ``results.parquet`` from chunks of rows kept on disk until the last, so a grid of a
million cases is written in the memory of one chunk.

The files are exactly those written in one piece from the whole list of rows would be:
the same columns, cells and column types (a column's type is inferred from all of its
values: each chunk's types are inferred alike and widened together at the end, an integer
column with a fractional value anywhere a float column, a column without any value a float
column), and for a table of at most :data:`ROWS_PER_GROUP` rows the same bytes (a longer
one is written in row groups of that many rows). Both files land under
their names only when :meth:`TableWriter.finish` is called (temporary files renamed over
them); an interrupted run leaves the tables of the run before.
"""

from __future__ import annotations

import csv
import json
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any, Self

from glshade.errors import GlshadeError
from glshade.files import check_output
from glshade.sweep import store
from glshade.sweep.spec import SweepSpec

#: Most rows written to ``results.parquet`` in one piece (a row group, about 20 MiB).
ROWS_PER_GROUP = 65_536


class TableWriter:
    """``results.parquet`` and ``results.csv`` of ``spec`` in ``out_dir``, written from
    rows given in the table's order (:meth:`add`), under their names by :meth:`finish`;
    a context manager that removes its temporary files whatever happens."""

    def __init__(self, out_dir: Path, spec: SweepSpec) -> None:
        self.out_dir, self.spec = Path(out_dir), spec
        self.columns = ["case_id", *spec.columns, *store.output_names(spec.method)]
        self.rows = 0
        _remove_stale(self.out_dir)
        self._csv = _Temporary(self.out_dir / store.CSV, text=True)
        self._spill = _Temporary(self.out_dir / store.PARQUET)
        self._csv_rows = csv.DictWriter(
            self._csv.file, fieldnames=self.columns, lineterminator="\n"
        )
        self._csv_rows.writeheader()
        self._pieces: list[tuple[int, int]] = []  # (offset, length) of each spilled chunk
        self._types: list = [None] * len(self.columns)  # each column's type so far

    def add(self, rows: list[dict[str, Any]]) -> None:
        """The next rows of the table (a row's missing columns are empty cells)."""
        if not rows:
            return
        import pyarrow as pa

        for row in rows:
            self._csv_rows.writerow({name: _csv_cell(row.get(name)) for name in self.columns})
        types = [_inferred(name, rows) for name in self.columns]
        table = pa.Table.from_pylist(
            [{name: _cell(row.get(name)) for name in self.columns} for row in rows],
            schema=pa.schema(list(zip(self.columns, types, strict=True))),
        )
        self._types = [_widened(a, b) for a, b in zip(self._types, types, strict=True)]
        spill = self._spill.file
        start = spill.tell()
        with pa.ipc.new_stream(spill, table.schema) as stream:
            stream.write_table(table)
        self._pieces.append((start, spill.tell() - start))
        self.rows += len(rows)

    def finish(self) -> None:
        """Both tables under their names: ``results.parquet`` (the manifest in its
        metadata) first, then ``results.csv``."""
        import pyarrow.parquet as pq

        schema = self._schema()
        parquet = _Temporary(self.out_dir / store.PARQUET)
        try:
            with pq.ParquetWriter(parquet.file, schema) as writer:
                for group in self._groups(schema):
                    writer.write_table(group)
            parquet.replace()
        finally:
            parquet.discard()
        self._csv.replace()

    def _schema(self):
        """The table's columns and their types (a column without values: float), the
        sweep's manifest in its metadata."""
        import pyarrow as pa

        fields = [
            (name, pa.float64() if kind is None or pa.types.is_null(kind) else kind)
            for name, kind in zip(self.columns, self._types, strict=True)
        ]
        manifest = json.dumps(self.spec.manifest()).encode()
        return pa.schema(fields).with_metadata({b"glshade": manifest})

    def _groups(self, schema) -> Iterator:
        """The spilled chunks read back, cast to the table's types and joined into
        pieces of at most :data:`ROWS_PER_GROUP` rows (an empty table: one empty piece)."""
        import pyarrow as pa

        self._spill.file.flush()
        if not self._pieces:
            yield schema.empty_table()
            return
        group: list = []
        rows = 0
        with pa.OSFile(self._spill.path) as source:  # one piece in memory at a time
            for start, length in self._pieces:
                source.seek(start)
                with pa.ipc.open_stream(source.read_buffer(length)) as reader:
                    table = reader.read_all().cast(schema)
                if group and rows + table.num_rows > ROWS_PER_GROUP:
                    yield pa.concat_tables(group)
                    group, rows = [], 0
                group.append(table)
                rows += table.num_rows
        yield pa.concat_tables(group)

    def close(self) -> None:
        """Remove what is left of the temporary files."""
        self._csv.discard()
        self._spill.discard()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _inferred(name: str, rows: list[dict[str, Any]]):
    """A column's type from its values (pyarrow's, an integer column with a fractional
    value a float column), but null where it has none (another chunk may have some)."""
    import pyarrow as pa

    values = [_cell(row.get(name)) for row in rows if row.get(name) is not None]
    if not values:
        return pa.null()
    kind = pa.array(values).type
    if pa.types.is_integer(kind) and any(isinstance(v, float) for v in values):
        kind = pa.float64()
    return kind


def _cell(value: Any) -> Any:
    """A table's cell in ``results.parquet``: a tuple as a list."""
    return list(value) if isinstance(value, tuple) else value


def _csv_cell(value: Any) -> Any:
    """A table's cell in ``results.csv``: a list or a mapping as JSON, nothing empty."""
    if isinstance(value, (list, tuple, dict)):
        return json.dumps(list(value) if isinstance(value, tuple) else value)
    return "" if value is None else value


def _widened(before, now):
    """The type of a column whose values so far had type ``before`` (None: no chunk yet)
    and whose next chunk's have ``now``: the type inferred from all of them (null and
    a type: that type; integers and floats: float; lists of them alike)."""
    import pyarrow as pa

    if before is None or before == now:
        return now
    try:
        merged = pa.unify_schemas(
            [pa.schema([("c", before)]), pa.schema([("c", now)])], promote_options="permissive"
        )
    except (pa.ArrowInvalid, pa.ArrowTypeError) as exc:
        raise GlshadeError(f"results table: a column holds values of two kinds ({exc})") from None
    return merged.field("c").type


def _remove_stale(out_dir: Path) -> None:
    """The temporary tables a killed run left in ``out_dir`` (whose lock this run holds),
    removed: only files named as :class:`_Temporary` names them."""
    for name in (store.PARQUET, store.CSV):
        for path in out_dir.glob(f".{name}.*.tmp"):
            if path.is_file() and not path.is_symlink():
                path.unlink()


class _Temporary:
    """A temporary file beside ``target`` (which is checked to be a regular file to
    be), with the permissions a plain ``open`` gives, until :meth:`replace` renames it
    over ``target`` or :meth:`discard` removes it."""

    def __init__(self, target: Path, text: bool = False) -> None:
        self.target = check_output(target, "--out")
        try:
            fd, self.path = tempfile.mkstemp(
                prefix=f".{self.target.name}.", suffix=".tmp", dir=self.target.parent
            )
        except OSError as exc:
            raise GlshadeError(f"--out {target}: cannot write here ({exc.strerror})") from None
        mask = os.umask(0)
        os.umask(mask)
        os.fchmod(fd, 0o666 & ~mask)
        self.file: IO = (
            os.fdopen(fd, "w", encoding="utf-8", newline="") if text else os.fdopen(fd, "w+b")
        )

    def replace(self) -> None:
        try:
            self.file.flush()
            os.fsync(self.file.fileno())
            self.file.close()
            os.replace(self.path, self.target)
        except OSError as exc:
            raise GlshadeError(f"--out {self.target}: cannot write it ({exc.strerror})") from None

    def discard(self) -> None:
        self.file.close()
        try:
            os.unlink(self.path)
        except FileNotFoundError:
            pass
