"""What a study writes and reads back: the typed row of one case (:class:`CaseResult`:
the case's point of the plan, then the measurement's record, whose fields are the
columns of ``results.csv``), ``results.csv``, and the study's layout of the output
directory (:data:`STRIPES`) in the one store of every run (:mod:`glshade.measure.store`:
its manifest ``study.json``, its case files, what ``--overwrite`` removes). No GL here: a
planner or a Dask client reads results with it.

Each finished case is written as ``cases/<key>.json`` (plus a thumbnail of its image at
the best phase for the figure grids) atomically, so an interrupted run loses nothing and
a rerun with the same output directory skips what is done. ``results.csv`` is rebuilt
from the case files; its columns are :data:`COLUMNS` (documented in ``docs/results.md``).
"""

from __future__ import annotations

import csv
import functools
import io
from collections.abc import Iterable, Iterator, Mapping, Sequence
from contextlib import AbstractContextManager
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from glshade.errors import GlshadeError
from glshade.files import RESULTS_TABLE_BYTES, atomic_write_bytes, read_regular_text
from glshade.instruments.record import Column, Measurement
from glshade.measure import store
from glshade.measure.case_files import Rejected
from glshade.study.plan import PlanPoint, case_key


def point_field(unit: str, meaning: str) -> Any:
    """A study row's field of the case's point of the plan, with its unit and meaning."""
    return field(metadata={"unit": unit, "meaning": meaning, "role": "case"})


POINT_NAMES = ("surface", "theta_deg", "sigma2_mm2", "dmax_mm", "period_mm")


@dataclass(frozen=True)
class PlanRow(Mapping):
    """A study's row: the case's point of the plan (the fields :data:`POINT_NAMES`; each
    row class declares ``period_mm``, its own period), then its record's columns
    (:meth:`Record.columns <glshade.instruments.record.Record.columns>`). It reads as a
    mapping of those columns, in order (:meth:`table_columns`)."""

    surface: str = point_field(
        "",
        "base surface: flat, cylinder (R 70 mm, axis in the plane of incidence), sphere "
        "(R 70 mm), or the scene file of a free-form surface",
    )
    theta_deg: float = point_field(
        "deg", "camera elevation θ above the surface (90 = straight down)"
    )
    sigma2_mm2: float = point_field("mm²", "variance σ² of the Gaussian dent (isotropic)")
    dmax_mm: float = point_field("mm", "depth of the dent (0.003 mm = 3 µm)")

    @classmethod
    def table_columns(cls) -> tuple[Column, ...]:
        """The row's columns: the point's, then the record's."""
        return _table_columns(cls)

    @classmethod
    def of_point(cls, point: PlanPoint, period_mm: float, record: Any) -> Any:
        """A case's row: its point of the plan and its record."""
        surface, theta, sigma2, dmax = point
        return cls(
            surface=surface,  # type: ignore[call-arg]
            theta_deg=theta,
            sigma2_mm2=sigma2,
            dmax_mm=dmax,
            period_mm=period_mm,
            **record.row(),
        )

    @classmethod
    def from_row(cls, row: Mapping[str, Any]) -> Any:
        """From a case file's object or a table's row (text); extra keys ignored."""
        return cls(**{c.name: row[c.name] for c in cls.table_columns()})

    @property
    def case(self) -> PlanPoint:
        """``(surface, θ, σ², dmax)``: the case's point of the plan."""
        return self.surface, self.theta_deg, self.sigma2_mm2, self.dmax_mm

    # ------------------------------------------------------------ mapping of the columns
    def __getitem__(self, name: str) -> Any:
        if name not in _names(type(self)):
            raise KeyError(name)
        return getattr(self, name)

    def __iter__(self) -> Iterator[str]:
        return iter(c.name for c in self.table_columns())

    def __len__(self) -> int:
        return len(self.table_columns())


@functools.cache
def _table_columns(row_class: Any) -> tuple[Column, ...]:
    point = [f for f in fields(row_class) if f.name in POINT_NAMES]
    point.sort(key=lambda f: POINT_NAMES.index(f.name))
    return (
        *(Column(f.name, f.metadata["unit"], f.metadata["meaning"], "case") for f in point),
        *row_class.columns(),
    )


@functools.cache
def _names(row_class: Any) -> frozenset[str]:
    return frozenset(c.name for c in _table_columns(row_class))


@dataclass(frozen=True)
class CaseResult(PlanRow, Measurement):
    """One case of the study: its point of the plan (surface, θ, σ², dmax, the stripe
    period) and its :class:`~glshade.instruments.record.Measurement`. Its columns, in order:
    :data:`COLUMNS`; the row also reads as a mapping of them."""

    period_mm: float = point_field(
        "mm", "stripe period on the emitter (2 mm; 10 mm on the sphere, as in the paper)"
    )


#: The columns of ``results.csv``: the case's point of the plan, then the record's.
COLUMNS: tuple[Column, ...] = CaseResult.table_columns()


# --------------------------------------------------------------------------- output dir
#: The files a study writes at the top of its directory (the case files live in
#: ``cases/``); ``--overwrite`` removes exactly these, never anything else.
STUDY_FILES = (
    "results.csv",
    "report.md",
    "grid_*.png",
    "visibility_*.png",
    "law_vs_simulation.png",
    "fig09_contour_overlay*.png",
)


def _another_plan(stored: dict, wanted: dict) -> str:
    """What a directory of another plan holds, in a refusal: its first three differences."""
    keys = store.changed(stored, wanted)[:3]
    shown = "; ".join(
        f"{k}: {_short(stored.get(k))} there, {_short(wanted.get(k))} asked" for k in keys
    )
    return f"a study with another plan ({shown})"


def _short(value: object) -> str:
    if isinstance(value, list):
        return ",".join(f"{v:g}" if isinstance(v, float) else str(v) for v in value)
    return "unset" if value is None else str(value)


def _with_metric_defaults(out_dir: Path, stored: store.Stored) -> store.Stored:
    """A manifest written before a metric setting existed meant its default: fill it in."""
    if not stored or not isinstance(stored.get("metric"), dict):
        return stored
    from dataclasses import asdict

    from glshade.metrics.visibility import MetricSettings

    return {**stored, "metric": {**asdict(MetricSettings()), **stored["metric"]}}


#: The paper's stripe study (``glshade paper``): its manifest ``study.json``, its case
#: files and thumbnails in ``cases/``; a plan of the same size and metric reuses them.
STRIPES = store.Layout(
    manifest="study.json",
    held=_another_plan,
    resume="with the same settings",
    files=STUDY_FILES,
    comparable=("size", "metric", "metric_version"),
    as_now=_with_metric_defaults,
)


def opened(
    out_dir: Path, manifest_data: dict, overwrite: bool = False, layout: store.Layout = STRIPES
) -> AbstractContextManager[list[Path]]:
    """``out_dir`` held for a study's run and tied to its plan (``manifest_data``, written
    as ``layout.manifest``) for the ``with`` block (:func:`glshade.measure.store.opened`).

    A directory that holds a study with another plan (other surfaces, angles, dents,
    size or metric) is refused, so a subset rerun can never silently shrink
    ``results.csv`` or leave stale figures beside a new report; with ``overwrite`` the
    old study's files (``layout.files``) are removed, and its case files too unless
    they were measured with the same size and metric (the new plan reuses them). Gives
    the files removed."""
    keys = _plan_keys(manifest_data)
    return store.opened(out_dir, layout, manifest_data, overwrite, keys=keys)


def _plan_keys(plan_dict: dict) -> set[str]:
    """The case keys of a plan as ``StudyPlan.to_dict`` wrote it."""
    lists = [plan_dict.get(k) or () for k in ("surfaces", "thetas", "sigma2s", "dmaxs")]
    return {
        case_key(s, t, v, d) for s in lists[0] for t in lists[1] for v in lists[2] for d in lists[3]
    }


# --------------------------------------------------------------------------- files
def finished(
    out_dir: Path,
    keys: Iterable[str],
    rejected: Rejected | None = None,
    layout: store.Layout = STRIPES,
    row_class: Any = None,
) -> dict[str, Any]:
    """The finished cases among ``keys`` (case keys, :func:`~glshade.study.plan.case_key`):
    their rows (of ``row_class``, default :class:`CaseResult`) by key. A case file not to
    be trusted (:func:`glshade.measure.store.load_cases`; or a value outside its column's
    type, range or words: :meth:`~glshade.instruments.record.Record.json_problem`; or another
    case's point) is left out, and ``rejected`` collects it with the reason: measure it
    again."""
    read = functools.partial(_read_row, row_class or CaseResult)
    return store.load_cases(out_dir, layout, keys, read, rejected)


def _read_row(kind: Any, data: dict, key: str) -> tuple[Any, str | None]:
    """A checked case file's record as a row of ``kind`` for case ``key``, or why not."""
    problem = kind.json_problem(data)
    if problem is not None:
        return None, problem
    try:
        row = kind.from_row(data)
    except (TypeError, ValueError, KeyError) as exc:
        return None, f"does not read as a case ({str(exc)[:80]})"
    if case_key(*row.case) != key:
        return None, f"holds the case {case_key(*row.case)}"
    return row, None


def write_case(
    out_dir: Path, result: Any, thumbnail: bytes | None = None, layout: store.Layout = STRIPES
) -> None:
    """A finished case on disk, in ``layout``'s folder: its thumbnail, and last its JSON
    (the "done" mark a rerun looks for), with its case id and checksum."""
    store.write_case(out_dir, layout, case_key(*result.case), dict(result), thumbnail)


def write_cases(
    out_dir: Path, results: Sequence[tuple[Any, bytes | None]], layout: store.Layout = STRIPES
) -> None:
    """Finished cases (each a result and its thumbnail or None) on disk as one group, with
    one flush for the group (:func:`glshade.measure.store.write_cases`: the thumbnails on
    the disk before any case file, the "done" mark a rerun looks for, is written)."""
    store.write_cases(
        out_dir, layout, [(case_key(*r.case), dict(r), image) for r, image in results]
    )


def write_results_csv(path: Path, rows: Sequence[PlanRow], row_class: Any = None) -> None:
    """A study's table, one row per case, its columns those of ``row_class`` (default:
    the rows' own; :class:`CaseResult` for none), atomically."""
    kind = row_class or (type(rows[0]) if rows else CaseResult)
    buffer = io.StringIO()
    names = [c.name for c in kind.table_columns()]
    writer = csv.DictWriter(buffer, fieldnames=names, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow(dict(row))
    atomic_write_bytes(Path(path), buffer.getvalue().encode(), within=Path(path).parent)


def read_results_csv(path: Path, row_class: Any = None) -> list[Any]:
    """A study's table back as typed rows of ``row_class`` (default :class:`CaseResult`,
    ``results.csv``), each value checked as a case file's is (its column's type, range
    and words: :func:`~glshade.instruments.record.value_problem`); one line naming the first
    row that is not one glshade writes."""
    kind = row_class or CaseResult
    text = read_regular_text(path, "results table", RESULTS_TABLE_BYTES)
    rows: list[Any] = []
    try:
        for raw in csv.DictReader(io.StringIO(text, newline="")):
            rows.append(_table_row(kind, raw, path, len(rows) + 1))
    except csv.Error as exc:
        raise GlshadeError(f"results table {path}: not a table glshade writes ({exc})") from None
    return rows


def _table_row(kind: Any, raw: dict, path: Path, number: int) -> Any:
    """Row ``number`` of the table ``path`` as a typed row, or one line saying why not."""
    try:
        row = kind.from_row(raw)
        problem = row.problem()
    except KeyError as exc:
        problem = f"lacks the column {exc}"
    except (TypeError, ValueError, OverflowError):
        problem = "holds a value that is not its column's type"
    if problem is None:
        return row
    raise GlshadeError(
        f"results table {path}: row {number} {problem}; rerun the study that wrote it, with "
        "this --out, to rebuild it from its case files"
    )
