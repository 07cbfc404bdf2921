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
from collections.abc import Iterator, Mapping
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

    surface: str = _column("", "base surface: flat, cylinder (R 70 mm, axis in the plane of incidence) or sphere (R 70 mm)")
    theta_deg: float = _column("deg", "camera elevation θ above the surface (90 = straight down)")
    sigma2_mm2: float = _column("mm²", "variance σ² of the Gaussian dent (isotropic)")
    dmax_mm: float = _column("mm", "depth of the dent (0.003 mm = 3 µm)")
    period_mm: float = _column("mm", "stripe period on the emitter (2 mm; 10 mm on the sphere, as in the paper)")
    visibility_px: float = _column("px", "the paper's metric: the largest distance between corresponding stripe contours "
                                   "over the phase sweep, whole pixels of the image (SPEC §6)")
    visibility_continuous_px: float = _column("px", "the limit of the paper's metric for a vanishing phase step and "
                                              "pixel size, by the same contour rules (sub-pixel)")
    deflection_px: float = _column("px", "how far the dent moves the emitter map: the largest distance between a row r "
                                   "and the row r0 where v0(r0) = v1(r), in a kept column; equals the continuous "
                                   "visibility where nothing folds")
    folded: bool = _column("", "True where the dent's emitter map runs against the defect-free one along some kept "
                           "column (the stripe map folds)")
    islands: int = _column("count", "the most stripe pieces the dent cuts off (touching neither a cut column nor the "
                           "border; beyond those the defect-free image has) at any phase; never measured")
    best_phase_mm: float = _column("mm", "stripe phase at which visibility_px was reached")
    unpaired_contours: int = _column("count", "stripes reaching a cut column or the border that found no partner at the "
                                     "best phase (0 in a healthy comparison)")
    offset_dx_px: int = _column("px", "registration offset applied to the defect image, columns (0 for rendered pairs)")
    offset_dy_px: int = _column("px", "registration offset applied to the defect image, rows (0 for rendered pairs)")
    unresolved_fraction: float = _column("fraction", "share of the kept pixels left out because the defect-free stripes "
                                         "span fewer than 4 px per period there (aliasing)")
    fold_ratio: float = _column("", "closed form 2 κ Dc De / ((Dc + De) sin θ), κ the largest tangential curvature of "
                                "base plus dent; the map folds where it exceeds 1 (docs/physics.md)")
    deflection_law_px: float = _column("px", "closed form of deflection_px (docs/physics.md)")
    visibility_law_px: float = _column("px", "closed form of visibility_continuous_px: the deflection, capped by a fold "
                                       "at b sqrt(2 ln(F/m)) (docs/physics.md)")
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


COLUMNS = tuple(Column(f.name, f.metadata["unit"], f.metadata["meaning"]) for f in fields(CaseResult))
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
    atomic_write_bytes(out_dir / "cases" / f"{key}.json", json.dumps(dict(result), indent=1).encode())


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
def prepare_out_dir(out_dir: Path, manifest_data: dict) -> None:
    """Create (or reuse) the output directory and write its ``study.json``; a directory
    that holds a study with other settings, or one measured with another version of the
    metric, is refused rather than mixed."""
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise GlshadeError(f"--out {out_dir}: is a file, expected a directory")
    try:
        (out_dir / "cases").mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise GlshadeError(f"--out {out_dir}: cannot create it ({exc.strerror})") from None
    probe = out_dir / ".glshade-write-test"
    try:
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise GlshadeError(f"--out {out_dir}: not writable ({exc.strerror})") from None
    manifest = out_dir / "study.json"
    if manifest.exists():
        try:
            stored = json.loads(manifest.read_text())
        except (OSError, ValueError):
            stored = None
        if stored is not None and _comparable(stored) != _comparable(manifest_data):
            raise GlshadeError(
                f"--out {out_dir}: holds a study with other settings or an older metric (see its study.json); "
                "use another directory or remove it"
            )
    atomic_write_bytes(manifest, json.dumps(manifest_data, indent=2).encode())


def _comparable(plan_dict: dict) -> dict:
    """The settings that change results (the case lists may differ: a rerun may add
    surfaces or angles to the same directory)."""
    return {k: plan_dict.get(k) for k in ("size", "metric", "metric_version")}
