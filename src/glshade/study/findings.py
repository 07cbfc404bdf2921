"""The paper's five findings (its section IV) checked against the study's results, advice for an
inspection engineer, and ``report.md``.

The numbers and verdicts are :mod:`glshade.study.findings_numbers`' (its names are
re-exported here); the words are the templates' (``templates/paper_report.md.j2`` and
the partials it includes), rendered by :func:`render_report`. :func:`evaluate` gives each
verdict with its words, as the report states it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from glshade.files import atomic_write_bytes
from glshade.study import findings_numbers as numbers
from glshade.study.findings_numbers import (
    CLASSES,
    GENTLE,
    HOLDS,
    METRICS,
    MIN_EFFECT,
    NEAR_BEST,
    NOT,
    PARTLY,
    PIXELS,
    STEEP,
    THRESHOLDS,
    PaperReport,
    Scale,
    best_thetas,
    near_best_thetas,
)
from glshade.study.formats import theta_ranges, um
from glshade.study.notation import laws_section, symbols_section
from glshade.study.stats import spearman
from glshade.study.status import split_measurable
from glshade.study.templating import macro, render, render_lines

__all__ = [
    "CLASSES",
    "GENTLE",
    "HOLDS",
    "METRICS",
    "MIN_EFFECT",
    "NEAR_BEST",
    "NOT",
    "PARTLY",
    "PIXELS",
    "STEEP",
    "Scale",
    "StatedVerdict",
    "advice",
    "best_thetas",
    "evaluate",
    "near_best_thetas",
    "render_report",
    "spearman",
    "theta_ranges",
    "um",
    "write_report",
]


@dataclass(frozen=True)
class StatedVerdict:
    """A verdict as the report states it: the finding, scope, metric and verdict of a
    :class:`~glshade.study.findings_numbers.Verdict`, its headline (``text``: the verdict
    with the numbers it is decided on and where it applies, "does not hold: σ² 1 -72%
    (ρ +0.45) (θ 85° → 5°); …") and its evidence, and the numbers themselves."""

    finding: int
    scope: str
    metric: str
    verdict: str
    text: str
    evidence: str
    numbers: numbers.Verdict


def evaluate(
    rows: Sequence[Mapping],
    metrics: Mapping[str, str] = METRICS,
    scales: Mapping[str, Scale] | None = None,
) -> list[StatedVerdict]:
    """Every verdict the rows support (:func:`glshade.study.findings_numbers.evaluate`),
    with its words."""
    headline = macro("_verdicts.md.j2", "headline")
    evidence = macro("_verdicts.md.j2", "evidence")
    return [
        StatedVerdict(
            v.finding, v.scope, v.metric, v.verdict, str(headline(v)), str(evidence(v)), v
        )
        for v in numbers.evaluate(rows, metrics, scales)
    ]


def advice(rows: Sequence[Mapping]) -> list[str]:
    """The report's camera advice, as its lines: for each surface what it is and what
    that does, then for each class of dent the θ that keep the dent most visible and the
    fold law's numbers. Measurable rows only."""
    return render_lines("paper_advice.md.j2", advice=numbers.advice(rows))


def render_report(
    report: PaperReport,
    notation: list[str],
    finding3,
    figures: Sequence[Path],
    timings=None,
) -> str:
    """``report.md``'s text: ``report``'s numbers, the notation's lines (symbols and
    laws), the realistic-optics section's numbers (None: none), the figures and the
    run's timings (None: a rewrite)."""
    return render(
        "paper_report.md.j2",
        report=report,
        rules=THRESHOLDS,
        notation=notation,
        finding3=finding3,
        figures=list(figures),
        timings=timings,
    )


def write_report(
    rows: Sequence[Mapping], out_dir: Path, plan, figures: list[Path], timings=None
) -> Path:
    """``report.md``: the symbols, the laws, the advice, the verdicts with their rules and
    numbers, the laws against the simulation, the folded cases, finding 3 under
    realistic optics (where ``finding3.csv`` is in ``out_dir``), and the figures. Rows
    that are not measurable (:func:`glshade.study.status.is_measurable`) are counted,
    not judged."""
    from glshade.study.finding3 import section

    everything = list(rows)
    ok, _ = split_measurable(everything)
    text = render_report(
        numbers.paper_report(everything, plan),
        symbols_section(ok, plan) + laws_section(),
        section(Path(out_dir)),
        figures,
        timings,
    )
    path = Path(out_dir) / "report.md"
    atomic_write_bytes(path, text.encode(), within=path.parent)
    return path
