"""What a study writes and reads back: the typed record of one case (:class:`CaseResult`,
whose fields are the columns of ``results.csv``), the case files, ``results.csv`` and the
output directory's manifest. No GL here: a planner or a Dask client reads results with it.

Each finished case is written as ``cases/<key>.json`` (plus a thumbnail of its image at
the best phase for the figure grids) atomically, so an interrupted run loses nothing and
a rerun with the same output directory skips what is done. ``results.csv`` is rebuilt
from the case files; its columns are :data:`COLUMNS` (documented in ``docs/results.md``).
"""

from __future__ import annotations

import csv
import io
import json
import os
import socket
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from glshade.errors import GlshadeError
from glshade.files import atomic_write_bytes
from glshade.study.plan import Case, case_key


def _column(unit: str, meaning: str) -> Any:
    return field(metadata={"unit": unit, "meaning": meaning})


@dataclass(frozen=True)
class CaseResult(Mapping):
    """One case of the study: its parameters, the three numbers, the closed forms and the
    timings. The fields are the columns of ``results.csv`` (in order, with their units
    and meanings: :data:`COLUMNS`); the record also reads as a mapping of them."""

    surface: str = _column(
        "",
        "base surface: flat, cylinder (R 70 mm, axis in the plane of incidence), sphere (R 70 mm), "
        "or the scene file of a free-form surface",
    )
    theta_deg: float = _column("deg", "camera elevation θ above the surface (90 = straight down)")
    sigma2_mm2: float = _column("mm²", "variance σ² of the Gaussian dent (isotropic)")
    dmax_mm: float = _column("mm", "depth of the dent (0.003 mm = 3 µm)")
    period_mm: float = _column(
        "mm", "stripe period on the emitter (2 mm; 10 mm on the sphere, as in the paper)"
    )
    visibility_px: float = _column(
        "px",
        "the paper's metric: the largest distance between corresponding stripe contours "
        "over the phase sweep, whole pixels of the image (SPEC §6)",
    )
    visibility_continuous_px: float = _column(
        "px",
        "the limit of the paper's metric for a vanishing phase step and "
        "pixel size, by the same contour rules (sub-pixel)",
    )
    deflection_px: float = _column(
        "px",
        "how far the dent moves the emitter map: the largest distance between a row r "
        "and the row r0 where v0(r0) = v1(r), in a kept column; equals the continuous "
        "visibility where nothing folds",
    )
    folded: bool = _column(
        "",
        "True where the dent's emitter map runs against the defect-free one along some kept "
        "column (the stripe map folds)",
    )
    islands: int = _column(
        "count",
        "the most stripe pieces the dent cuts off (touching neither a cut column nor the "
        "border; beyond those the defect-free image has) at any phase; never measured",
    )
    best_phase_mm: float = _column("mm", "stripe phase at which visibility_px was reached")
    unpaired_contours: int = _column(
        "count",
        "stripes reaching a cut column or the border that found no partner at the "
        "best phase (0 in a healthy comparison)",
    )
    offset_dx_px: int = _column(
        "px", "registration offset applied to the defect image, columns (0 for rendered pairs)"
    )
    offset_dy_px: int = _column(
        "px", "registration offset applied to the defect image, rows (0 for rendered pairs)"
    )
    unresolved_fraction: float = _column(
        "fraction",
        "share of the kept pixels left out because the defect-free stripes "
        "span fewer than 4 px per period there (aliasing)",
    )
    fold_ratio: float = _column(
        "",
        "closed form 2 κ Dc De / ((Dc + De) sin θ), κ the largest tangential curvature of "
        "base plus dent; the map folds where it exceeds 1 (docs/physics.md)",
    )
    deflection_law_px: float = _column("px", "closed form of deflection_px (docs/physics.md)")
    visibility_law_px: float = _column(
        "px",
        "closed form of visibility_continuous_px: the deflection, capped by a fold "
        "at b sqrt(2 ln(F/m)) (docs/physics.md)",
    )
    trace_s: float = _column("s", "time to trace the dent's emitter map (GL)")
    shade_s: float = _column("s", "time to binarise the defect image at every phase")
    contours_s: float = _column("s", "time of the contour analysis over the phase sweep (OpenCV)")
    continuous_s: float = _column("s", "time of the deflection and the continuous limit")

    def __post_init__(self) -> None:
        for f in fields(self):  # typed whatever it was read from (JSON, CSV text, NumPy)
            object.__setattr__(self, f.name, _PARSE[f.type](getattr(self, f.name)))

    @classmethod
    def from_row(cls, row: Mapping[str, Any]) -> CaseResult:
        """From a case file's object or a ``results.csv`` row (text); extra keys ignored."""
        return cls(**{name: row[name] for name in CSV_COLUMNS})

    @property
    def case(self) -> Case:
        """``(surface, θ, σ², dmax)``: the case's place in the plan."""
        return self.surface, self.theta_deg, self.sigma2_mm2, self.dmax_mm

    # ------------------------------------------------------------ mapping of the columns
    def __getitem__(self, name: str) -> Any:
        if name not in _NAMES:
            raise KeyError(name)
        return getattr(self, name)

    def __iter__(self) -> Iterator[str]:
        return iter(CSV_COLUMNS)

    def __len__(self) -> int:
        return len(CSV_COLUMNS)


def _boolean(value: Any) -> bool:
    return value == "True" if isinstance(value, str) else bool(value)


_PARSE = {"str": str, "float": float, "int": int, "bool": _boolean}


@dataclass(frozen=True)
class Column:
    """One column of ``results.csv``: its name, unit and meaning (docs/results.md)."""

    name: str
    unit: str
    meaning: str


COLUMNS = tuple(
    Column(f.name, f.metadata["unit"], f.metadata["meaning"]) for f in fields(CaseResult)
)
CSV_COLUMNS = [c.name for c in COLUMNS]
_NAMES = frozenset(CSV_COLUMNS)
TIMING_COLUMNS = ("trace_s", "shade_s", "contours_s", "continuous_s")


def columns_markdown() -> str:
    """The table of ``docs/results.md``."""
    lines = ["| column | unit | meaning |", "|---|---|---|"]
    lines += [f"| `{c.name}` | {c.unit or '—'} | {c.meaning} |" for c in COLUMNS]
    return "\n".join(lines)


# --------------------------------------------------------------------------- files
def load_case(path: Path) -> CaseResult | None:
    """A finished case's record, or None (missing, or from an older or interrupted
    writer: recompute)."""
    try:
        row = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(row, dict) or not _NAMES <= set(row):
        return None
    try:
        return CaseResult.from_row(row)
    except (TypeError, ValueError):
        return None


def write_case(out_dir: Path, result: CaseResult, thumbnail: bytes | None) -> None:
    """A finished case on disk: its thumbnail, and last its JSON (the "done" mark a rerun
    looks for)."""
    key = case_key(*result.case)
    if thumbnail is not None:
        atomic_write_bytes(out_dir / "cases" / f"{key}.png", thumbnail)
    atomic_write_bytes(
        out_dir / "cases" / f"{key}.json", json.dumps(dict(result), indent=1).encode()
    )


def write_results_csv(path: Path, rows: list[CaseResult]) -> None:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=CSV_COLUMNS, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow(dict(row))
    atomic_write_bytes(Path(path), buffer.getvalue().encode())


def read_results_csv(path: Path) -> list[CaseResult]:
    """``results.csv`` back as typed records."""
    with open(path, newline="") as fh:
        return [CaseResult.from_row(raw) for raw in csv.DictReader(fh)]


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
LOCK_NAME = ".glshade.lock"
OWNER_NAME = ".glshade.lock.json"


@contextmanager
def study_lock(out_dir: Path, command: str = "glshade paper") -> Iterator[None]:
    """Hold the output directory for the whole run: a second run on it (in another
    process) is refused at once with a line naming the holder (pid, host, start time,
    command). The lock is an OS file lock (``filelock``): it dies with its process, so a
    killed run never leaves the directory locked. Re-entrant within a process."""
    from filelock import FileLock, Timeout

    out_dir = Path(out_dir)
    _make_dir(out_dir)
    lock = FileLock(out_dir / LOCK_NAME, timeout=0, is_singleton=True)
    try:
        lock.acquire()
    except Timeout:
        raise GlshadeError(
            f"--out {out_dir}: in use by {_owner(out_dir)}; wait for it to finish, or choose another "
            "--out"
        ) from None
    first = lock.lock_counter == 1
    try:
        if first:
            owner = {
                "pid": os.getpid(),
                "host": socket.gethostname(),
                "command": command,
                "since": time.strftime("%Y-%m-%d %H:%M:%S"),
            }
            atomic_write_bytes(out_dir / OWNER_NAME, json.dumps(owner).encode(), "--out")
        yield
    finally:
        if first:
            with suppress(OSError):
                (out_dir / OWNER_NAME).unlink()
        lock.release()


def _owner(out_dir: Path) -> str:
    try:
        owner = json.loads((out_dir / OWNER_NAME).read_text())
        return (
            f"'{owner['command']}' (pid {owner['pid']} on {owner['host']}, since {owner['since']})"
        )
    except (OSError, ValueError, KeyError, TypeError):
        return "another glshade run"


def _make_dir(out_dir: Path) -> None:
    if "\0" in str(out_dir):
        raise GlshadeError(f"--out {str(out_dir)!r}: expected a directory path")
    if out_dir.exists() and not out_dir.is_dir():
        raise GlshadeError(f"--out {out_dir}: is not a directory")
    try:
        (out_dir / "cases").mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise GlshadeError(f"--out {out_dir}: cannot create it ({exc.strerror})") from None
    if not os.access(out_dir, os.W_OK | os.X_OK):
        raise GlshadeError(f"--out {out_dir}: not writable")


def prepare_out_dir(out_dir: Path, manifest_data: dict, overwrite: bool = False) -> list[Path]:
    """Create (or reuse) the output directory and write its ``study.json``.

    A directory that holds a study with another plan (other surfaces, angles, dents,
    size or metric) is refused, so a subset rerun can never silently shrink
    ``results.csv`` or leave stale figures beside a new report; with ``overwrite`` the
    old study's files (:data:`STUDY_FILES`) are removed, and its case files too unless
    they were measured with the same size and metric (the new plan reuses them).
    Returns the files removed."""
    out_dir = Path(out_dir)
    _make_dir(out_dir)
    manifest_data = json.loads(json.dumps(manifest_data))  # as it reads back: lists, not tuples
    manifest = out_dir / "study.json"
    stored = _with_metric_defaults(_read_manifest(manifest))
    removed: list[Path] = []
    if stored is not None and stored != manifest_data:
        if not overwrite:
            raise GlshadeError(
                f"--out {out_dir}: holds a study with another plan ({_difference(stored, manifest_data)}); rerun "
                "with the same settings to resume it, add --overwrite to replace it, or choose another --out"
            )
        removed = _remove_stale(
            out_dir,
            keep_cases=_comparable(stored) == _comparable(manifest_data),
            cases=_plan_keys(manifest_data),
        )
    atomic_write_bytes(manifest, json.dumps(manifest_data, indent=2).encode(), "--out")
    return removed


def _with_metric_defaults(stored: dict | None) -> dict | None:
    """A manifest written before a metric setting existed meant its default: fill it in."""
    if not stored or not isinstance(stored.get("metric"), dict):
        return stored
    from dataclasses import asdict

    from glshade.metrics.visibility import MetricSettings

    return {**stored, "metric": {**asdict(MetricSettings()), **stored["metric"]}}


def _read_manifest(manifest: Path) -> dict | None:
    try:
        stored = json.loads(manifest.read_text())
    except FileNotFoundError:
        return None
    except (OSError, ValueError):
        return {}  # unreadable: a study of unknown plan
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


def _remove_stale(out_dir: Path, keep_cases: bool, cases: set[str]) -> list[Path]:
    """Remove what ``--overwrite`` replaces: the old study's figures, tables and report,
    and its case files that the new plan cannot reuse."""
    doomed = [
        path for pattern in STUDY_FILES for path in sorted(out_dir.glob(pattern)) if path.is_file()
    ]
    for path in sorted((out_dir / "cases").glob("*")):
        reusable = keep_cases and path.stem in cases
        if path.suffix in (".json", ".png") and path.is_file() and not reusable:
            doomed.append(path)
    for path in doomed:
        path.unlink()
    return doomed


def _comparable(plan_dict: dict) -> dict:
    """The settings that change each case's numbers (the case lists may differ)."""
    return {k: plan_dict.get(k) for k in ("size", "metric", "metric_version")}
