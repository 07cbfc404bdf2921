"""What a study writes and reads back: the typed row of one case (:class:`CaseResult`:
the case's point of the plan, then the measurement's record, whose fields are the
columns of ``results.csv``), the case files, ``results.csv`` and the output directory's
manifest. No GL here: a planner or a Dask client reads results with it.

Each finished case is written as ``cases/<key>.json`` (plus a thumbnail of its image at
the best phase for the figure grids) atomically, so an interrupted run loses nothing and
a rerun with the same output directory skips what is done. ``results.csv`` is rebuilt
from the case files; its columns are :data:`COLUMNS` (documented in ``docs/results.md``).
"""

from __future__ import annotations

import csv
import functools
import io
import json
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from glshade.errors import GlshadeError
from glshade.files import (
    RESULTS_TABLE_BYTES,
    atomic_write_bytes,
    read_regular,
    read_regular_text,
    remove_inside,
)
from glshade.measure.case_files import Rejected, case_file_bytes, read_case_file
from glshade.measure.locks import make_out_dir
from glshade.measure.record import Column, Measurement, columns_markdown
from glshade.study.plan import PlanPoint, case_key


def point_field(unit: str, meaning: str) -> Any:
    """A study row's field of the case's point of the plan, with its unit and meaning."""
    return field(metadata={"unit": unit, "meaning": meaning, "role": "case"})


POINT_NAMES = ("surface", "theta_deg", "sigma2_mm2", "dmax_mm", "period_mm")


@dataclass(frozen=True)
class PlanRow(Mapping):
    """A study's row: the case's point of the plan (the fields :data:`POINT_NAMES`; each
    row class declares ``period_mm``, its own period), then its record's columns
    (:meth:`Record.columns <glshade.measure.record.Record.columns>`). It reads as a
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
    period) and its :class:`~glshade.measure.record.Measurement`. Its columns, in order:
    :data:`COLUMNS`; the row also reads as a mapping of them."""

    period_mm: float = point_field(
        "mm", "stripe period on the emitter (2 mm; 10 mm on the sphere, as in the paper)"
    )


#: The columns of ``results.csv``: the case's point of the plan, then the record's.
COLUMNS: tuple[Column, ...] = CaseResult.table_columns()
CSV_COLUMNS = [c.name for c in COLUMNS]


def results_markdown() -> str:
    """The table of ``docs/results.md``."""
    return columns_markdown(COLUMNS)


# --------------------------------------------------------------------------- files
def load_case(path: Path, rejected: Rejected | None = None, row_class: Any = None) -> Any:
    """A finished case's record (of ``row_class``, default :class:`CaseResult`), or None:
    missing, or not to be trusted (:func:`~glshade.measure.case_files.read_case_file`: a
    failed checksum, another case's id, an older or interrupted writer, a value outside
    its column's type, range or words: :meth:`~glshade.measure.record.Record.json_problem`),
    which ``rejected`` collects with the reason: measure it again."""
    kind = row_class or CaseResult
    found = read_case_file(Path(path), Path(path).stem)
    row, problem = found.record, found.problem
    if row is not None:
        problem = _row_problem(row, kind, Path(path).stem)
    if problem is not None or row is None:
        if rejected is not None:
            rejected.add(Path(path), problem)
        return None
    return kind.from_row(row)


def _row_problem(row: dict, kind: Any, key: str) -> str | None:
    """Why a checked case file's record is still not a row of ``kind`` for case ``key``."""
    problem = kind.json_problem(row)
    if problem is not None:
        return problem
    try:
        parsed = kind.from_row(row)
    except (TypeError, ValueError, KeyError) as exc:
        return f"does not read as a case ({str(exc)[:80]})"
    if case_key(*parsed.case) != key:
        return f"holds the case {case_key(*parsed.case)}"
    return None


def write_case(out_dir: Path, result: Any, thumbnail: bytes | None, cases: str = "cases") -> None:
    """A finished case on disk, in the folder ``cases``: its thumbnail, and last its JSON
    (the "done" mark a rerun looks for), with its case id and checksum."""
    key = case_key(*result.case)
    if thumbnail is not None:
        atomic_write_bytes(out_dir / cases / f"{key}.png", thumbnail, within=out_dir)
    data = case_file_bytes(key, json.loads(json.dumps(dict(result))))
    atomic_write_bytes(out_dir / cases / f"{key}.json", data, within=out_dir)


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
    and words: :func:`~glshade.measure.record.value_problem`); one line naming the first
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


@dataclass(frozen=True)
class Layout:
    """Where one kind of study keeps its files in an output directory: its manifest, its
    case files' folder, the files ``--overwrite`` removes (glob patterns) and the manifest
    keys that change each case's numbers (case files of a plan that differs only
    elsewhere are reused). Two layouts share a directory without touching each other's
    files: the paper's stripe study and its study under phase measuring."""

    manifest: str = "study.json"
    cases: str = "cases"
    files: tuple[str, ...] = STUDY_FILES
    comparable: tuple[str, ...] = ("size", "metric", "metric_version")


#: The paper's stripe study (``glshade paper``).
STRIPES = Layout()


def prepare_out_dir(
    out_dir: Path, manifest_data: dict, overwrite: bool = False, layout: Layout = STRIPES
) -> list[Path]:
    """Create (or reuse) the output directory and write its manifest (``study.json`` for
    the stripe study, ``layout.manifest`` in general).

    A directory that holds a study with another plan (other surfaces, angles, dents,
    size or metric) is refused, so a subset rerun can never silently shrink
    ``results.csv`` or leave stale figures beside a new report; with ``overwrite`` the
    old study's files (:data:`STUDY_FILES`) are removed, and its case files too unless
    they were measured with the same size and metric (the new plan reuses them).
    Returns the files removed."""
    out_dir = Path(out_dir)
    make_out_dir(out_dir)
    manifest_data = json.loads(json.dumps(manifest_data))  # as it reads back: lists, not tuples
    manifest = out_dir / layout.manifest
    stored = _with_metric_defaults(_read_manifest(manifest))
    removed: list[Path] = []
    if stored is not None and stored != manifest_data:
        if not overwrite:
            raise GlshadeError(
                f"--out {out_dir}: holds a study with another plan "
                f"({_difference(stored, manifest_data)}); rerun "
                "with the same settings to resume it, add --overwrite to replace it, or choose "
                "another --out"
            )
        removed = _remove_stale(
            out_dir,
            keep_cases=_comparable(stored, layout) == _comparable(manifest_data, layout),
            cases=_plan_keys(manifest_data),
            layout=layout,
        )
    atomic_write_bytes(
        manifest, json.dumps(manifest_data, indent=2).encode(), "--out", within=out_dir
    )
    return removed


def _with_metric_defaults(stored: dict | None) -> dict | None:
    """A manifest written before a metric setting existed meant its default: fill it in."""
    if not stored or not isinstance(stored.get("metric"), dict):
        return stored
    from dataclasses import asdict

    from glshade.metrics.visibility import MetricSettings

    return {**stored, "metric": {**asdict(MetricSettings()), **stored["metric"]}}


def _read_manifest(manifest: Path) -> dict | None:
    """The study's manifest; None where there is none; {} where it cannot be read (a
    study of unknown plan). A FIFO or device in its place is refused, never read."""
    if not manifest.exists() and not manifest.is_symlink():
        return None
    try:
        stored = json.loads(read_regular(manifest, "--out"))
    except (ValueError, RecursionError):
        return {}
    return stored if isinstance(stored, dict) else {}


def _difference(stored: dict, wanted: dict) -> str:
    keys = [k for k in sorted(set(stored) | set(wanted)) if stored.get(k) != wanted.get(k)]
    return "; ".join(
        f"{k}: {_short(stored.get(k))} there, {_short(wanted.get(k))} asked" for k in keys[:3]
    )


def _short(value: object) -> str:
    if isinstance(value, list):
        return ",".join(f"{v:g}" if isinstance(v, float) else str(v) for v in value)
    return "unset" if value is None else str(value)


def _plan_keys(plan_dict: dict) -> set[str]:
    """The case keys of a plan as ``StudyPlan.to_dict`` wrote it."""
    lists = [plan_dict.get(k) or () for k in ("surfaces", "thetas", "sigma2s", "dmaxs")]
    return {
        case_key(s, t, v, d) for s in lists[0] for t in lists[1] for v in lists[2] for d in lists[3]
    }


def _remove_stale(
    out_dir: Path, keep_cases: bool, cases: set[str], layout: Layout = STRIPES
) -> list[Path]:
    """Remove what ``--overwrite`` replaces: the old study's figures, tables and report,
    and its case files that the new plan cannot reuse."""
    doomed = [path for pattern in layout.files for path in sorted(out_dir.glob(pattern))]
    folder = out_dir / layout.cases
    if folder.is_dir() and not folder.is_symlink():
        for path in sorted(folder.glob("*")):
            reusable = keep_cases and path.stem in cases
            if path.suffix in (".json", ".png") and not reusable:
                doomed.append(path)
    return [path for path in doomed if remove_inside(out_dir, path)]


def _comparable(plan_dict: dict, layout: Layout = STRIPES) -> dict:
    """The settings that change each case's numbers (the case lists may differ)."""
    return {k: plan_dict.get(k) for k in layout.comparable}
