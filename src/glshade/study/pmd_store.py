"""What the study under phase measuring writes and reads back, beside the stripe study in
the same directory: the typed row of one case (:class:`PmdCaseResult`: the case's point
of the plan, then the :class:`~glshade.measure.record.PmdMeasurement`), its case file
``pmd_cases/<key>.json`` (written atomically, the "done" mark a rerun looks for),
``pmd_results.csv`` rebuilt from them, and the manifest ``pmd_study.json``
(:data:`PMD_LAYOUT`). No GL here."""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from glshade.files import atomic_write_bytes
from glshade.measure.record import PMD_COLUMNS, Column, PmdMeasurement, columns_markdown
from glshade.study.plan import PlanPoint, case_key
from glshade.study.store import Layout

#: The PMD study's files in an output directory (``--overwrite`` removes only these).
PMD_LAYOUT = Layout(
    manifest="pmd_study.json",
    cases="pmd_cases",
    files=("pmd_results.csv", "pmd_report.md", "pmd_*.png"),
    comparable=("size", "chain", "codings", "settings", "pmd_study_version"),
)
RESULTS_NAME = "pmd_results.csv"
REPORT_NAME = "pmd_report.md"


def _point(unit: str, meaning: str) -> Any:
    return field(metadata={"unit": unit, "meaning": meaning, "role": "case"})


@dataclass(frozen=True)
class PmdCaseResult(PmdMeasurement, Mapping):
    """One case of the study under phase measuring: its point of the plan (surface, θ,
    σ², dmax, the finest fringe period) and what the station measured. Its columns, in
    order: :data:`PMD_STUDY_COLUMNS`; the row also reads as a mapping of them."""

    surface: str = _point(
        "",
        "base surface: flat, cylinder (R 70 mm, axis in the plane of incidence), sphere "
        "(R 70 mm), or the scene file of a free-form surface",
    )
    theta_deg: float = _point("deg", "camera elevation θ above the surface (90 = straight down)")
    sigma2_mm2: float = _point("mm²", "variance σ² of the Gaussian dent (isotropic)")
    dmax_mm: float = _point("mm", "depth of the dent (0.003 mm = 3 µm)")
    period_mm: float = _point(
        "mm",
        "the finest fringe period on the screen: the shortest whole mm, at least 2, spanning 3 "
        "pixels at every θ (1024²: 2 mm; 10 mm on the sphere; docs/study.md)",
    )

    @classmethod
    def of_point(cls, point: PlanPoint, period_mm: float, record: PmdMeasurement) -> PmdCaseResult:
        surface, theta, sigma2, dmax = point
        return cls(
            surface=surface,
            theta_deg=theta,
            sigma2_mm2=sigma2,
            dmax_mm=dmax,
            period_mm=period_mm,
            **record.row(),
        )

    @classmethod
    def from_row(cls, row: Mapping[str, Any]) -> PmdCaseResult:
        """From a case file's object or a ``pmd_results.csv`` row (text); extra keys
        ignored."""
        return cls(**{name: row[name] for name in PMD_STUDY_CSV_COLUMNS})

    @property
    def case(self) -> PlanPoint:
        return self.surface, self.theta_deg, self.sigma2_mm2, self.dmax_mm

    def __getitem__(self, name: str) -> Any:
        if name not in _NAMES:
            raise KeyError(name)
        return getattr(self, name)

    def __iter__(self) -> Iterator[str]:
        return iter(PMD_STUDY_CSV_COLUMNS)

    def __len__(self) -> int:
        return len(PMD_STUDY_CSV_COLUMNS)


POINT_NAMES = ("surface", "theta_deg", "sigma2_mm2", "dmax_mm", "period_mm")
#: The columns of ``pmd_results.csv``: the case's point of the plan, then the record's.
PMD_STUDY_COLUMNS: tuple[Column, ...] = (
    *(
        Column(f.name, f.metadata["unit"], f.metadata["meaning"], "case")
        for f in fields(PmdCaseResult)
        if f.name in POINT_NAMES
    ),
    *PMD_COLUMNS,
)
PMD_STUDY_CSV_COLUMNS = [c.name for c in PMD_STUDY_COLUMNS]
_NAMES = frozenset(PMD_STUDY_CSV_COLUMNS)


def pmd_results_markdown() -> str:
    """The table of ``pmd_results.csv``'s columns (docs/results.md)."""
    return columns_markdown(PMD_STUDY_COLUMNS)


def case_path(out_dir: Path, point: PlanPoint) -> Path:
    return Path(out_dir) / PMD_LAYOUT.cases / f"{case_key(*point)}.json"


def load_case(path: Path) -> PmdCaseResult | None:
    """A finished case's record, or None (missing, or from an older or interrupted
    writer: measure it again)."""
    try:
        row = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(row, dict) or not _NAMES <= set(row):
        return None
    try:
        return PmdCaseResult.from_row(row)
    except (TypeError, ValueError, KeyError):
        return None


def write_case(out_dir: Path, result: PmdCaseResult) -> None:
    """A finished case on disk, atomically."""
    atomic_write_bytes(case_path(out_dir, result.case), json.dumps(dict(result), indent=1).encode())


def write_results_csv(path: Path, rows: list[PmdCaseResult]) -> None:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=PMD_STUDY_CSV_COLUMNS, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow(dict(row))
    atomic_write_bytes(Path(path), buffer.getvalue().encode())


def read_results_csv(path: Path) -> list[PmdCaseResult]:
    """``pmd_results.csv`` back as typed records."""
    with open(path, newline="") as fh:
        return [PmdCaseResult.from_row(raw) for raw in csv.DictReader(fh)]
