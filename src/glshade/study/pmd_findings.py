"""The paper's question answered for a phase-measuring station, beside the paper's own
instrument: ``pmd_report.md``.

The numbers are :mod:`glshade.study.pmd_numbers`' (its names are re-exported here):
each case of the PMD study paired with the same case of the stripe study, the best θ by
SNR and by depth error beside the paper metric's, the folds, the closed forms, the
paper's findings for both instruments, the depths and every case. The words are the
template ``templates/pmd_report.md.j2``'s, rendered by :func:`render_pmd_report`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

from glshade.files import atomic_write_bytes
from glshade.study.findings_numbers import THRESHOLDS
from glshade.study.pmd_numbers import (
    DEPTH_TOLERANCE,
    LAW_TOLERANCE,
    PAPER_METRIC,
    PMD_METRICS,
    PMD_SCALES,
    PMD_STATUS_TEXT,
    Best,
    Pair,
    PmdReport,
    Recoded,
    Series,
    best_by_depth,
    best_by_paper,
    best_by_snr,
    best_theta,
    depth_error,
    fold_numbers,
    fringe_noise,
    judged_rows,
    law_status,
    noise_share,
    pair_rows,
    pmd_report,
    point_of,
    recoded,
    series,
)
from glshade.study.pmd_store import REPORT_NAME
from glshade.study.templating import render

__all__ = [
    "DEPTH_TOLERANCE",
    "LAW_TOLERANCE",
    "PAPER_METRIC",
    "PMD_METRICS",
    "PMD_SCALES",
    "PMD_STATUS_TEXT",
    "Best",
    "Pair",
    "Recoded",
    "Series",
    "best_by_depth",
    "best_by_paper",
    "best_by_snr",
    "best_theta",
    "depth_error",
    "fold_numbers",
    "fringe_noise",
    "judged_rows",
    "law_status",
    "noise_share",
    "pair_rows",
    "point_of",
    "recoded",
    "render_pmd_report",
    "series",
    "write_pmd_report",
]


def render_pmd_report(report: PmdReport, figures: Sequence[Path]) -> str:
    """``pmd_report.md``'s text: ``report``'s numbers and the figures."""
    return render("pmd_report.md.j2", report=report, rules=THRESHOLDS, figures=list(figures))


def write_pmd_report(
    pmd_rows: Sequence[Mapping],
    paper_rows: Sequence[Mapping],
    out_dir: Path,
    plan,
    figures: Sequence[Path],
    paper_size: int | None,
    seconds: float | None = None,
    computed: int | None = None,
) -> Path:
    """``pmd_report.md`` in ``out_dir``: the answer, the folds, the closed forms, the
    findings for both instruments, the depths, the figures and every case (``seconds``,
    ``computed``: what this run spent measuring, and on how many cases; None for a
    rewrite)."""
    report = pmd_report(pmd_rows, paper_rows, plan, paper_size, seconds, computed)
    path = Path(out_dir) / REPORT_NAME
    atomic_write_bytes(path, render_pmd_report(report, figures).encode(), within=path.parent)
    return path
