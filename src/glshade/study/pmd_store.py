"""What the study under phase measuring writes and reads back, beside the stripe study in
the same directory: the typed row of one case (:class:`PmdCaseResult`: the case's point
of the plan, then the :class:`~glshade.instruments.record.PmdMeasurement`), its case file
``pmd_cases/<key>.json`` (written atomically, the "done" mark a rerun looks for),
``pmd_results.csv`` rebuilt from them, and the manifest ``pmd_study.json``
(:data:`PMD_LAYOUT`). No GL here."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from glshade.instruments.record import Column, PmdMeasurement
from glshade.measure.case_files import Rejected
from glshade.study import store
from glshade.study.store import STRIPES, PlanRow, point_field

#: The PMD study's files in an output directory: its manifest, its case files' folder,
#: what ``--overwrite`` removes (only these: the stripe study beside it is never touched)
#: and the manifest keys that change each case's numbers.
PMD_LAYOUT = replace(
    STRIPES,
    manifest="pmd_study.json",
    cases="pmd_cases",
    images="pmd_cases",
    files=("pmd_results.csv", "pmd_report.md", "pmd_*.png"),
    comparable=("size", "chain", "codings", "settings", "pmd_study_version"),
)
RESULTS_NAME = "pmd_results.csv"
REPORT_NAME = "pmd_report.md"


@dataclass(frozen=True)
class PmdCaseResult(PlanRow, PmdMeasurement):
    """One case of the study under phase measuring: its point of the plan (surface, θ,
    σ², dmax, the finest fringe period) and what the station measured. Its columns, in
    order: :data:`PMD_STUDY_COLUMNS`; the row also reads as a mapping of them."""

    period_mm: float = point_field(
        "mm",
        "the finest fringe period on the screen: the shortest whole mm, at least 2, spanning 3 "
        "pixels at every θ (1024²: 2 mm; 10 mm on the sphere; docs/study.md)",
    )


#: The columns of ``pmd_results.csv``: the case's point of the plan, then the record's.
PMD_STUDY_COLUMNS: tuple[Column, ...] = PmdCaseResult.table_columns()


def finished(
    out_dir: Path, keys: Iterable[str], rejected: Rejected | None = None
) -> dict[str, Any]:
    """The finished cases among ``keys``: their records by key (what is not to be trusted
    ``rejected`` collects, with why: :func:`glshade.study.store.finished`)."""
    return store.finished(out_dir, keys, rejected, PMD_LAYOUT, PmdCaseResult)


def write_case(out_dir: Path, result: PmdCaseResult) -> None:
    """A finished case on disk, atomically, with its case id and checksum."""
    store.write_case(out_dir, result, None, PMD_LAYOUT)


def write_results_csv(path: Path, rows: list[PmdCaseResult]) -> None:
    """``pmd_results.csv``, atomically (the studies' one writer)."""
    store.write_results_csv(path, rows, PmdCaseResult)


def read_results_csv(path: Path) -> list[PmdCaseResult]:
    """``pmd_results.csv`` back as typed records."""
    return store.read_results_csv(path, PmdCaseResult)
