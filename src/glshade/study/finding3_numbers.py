"""The numbers of the finding-3 study (:mod:`glshade.study.finding3`): does finding 3
hold for each variant of the optics, the answer in numbers, the noise floors and the
margin over them, and the visibility tables. Plain values; the templates
``finding3_report.md.j2`` and ``finding3_section.md.j2`` word them.

A variant is anything with a ``key`` and a ``label``
(:class:`glshade.study.finding3.Variant`); a row is one line of ``finding3.csv``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from glshade.metrics.status import concerns
from glshade.study.stats import spearman

SIGMA2S = (1.0, 4.0, 9.0, 16.0)
GENTLE = (9.0, 16.0)
#: Finding 3 "holds" when visibility falls with θ (Spearman rho below this) and the low
#: views (θ <= 25°) beat the high ones (θ >= 65°) by at least this factor: a 2 % drift
#: is no reason to move a camera.
HOLDS_RHO = -0.5
HOLDS_GAIN = 1.1


class Named(Protocol):
    @property
    def key(self) -> str: ...

    @property
    def label(self) -> str: ...


def readable(row, key: str = "visibility_px") -> bool:
    """True when ``row``'s ``key`` can be read (its status does not concern it; rows
    without a status column are readable)."""
    return not concerns(str(row.get("status") or "ok"), key)


def series(
    rows, variant: str, sigma2: float, key: str = "visibility_px", measurable: bool = True
) -> tuple[np.ndarray, np.ndarray]:
    """θ and ``key`` of a variant's dent, sorted by θ: its readable rows (``measurable``)
    or the others."""
    chosen = sorted(
        (r["theta_deg"], r[key])
        for r in rows
        if r["variant"] == variant and r["sigma2_mm2"] == sigma2 and readable(r, key) == measurable
    )
    return np.array([c[0] for c in chosen]), np.array([c[1] for c in chosen], dtype=float)


def trend(
    rows, variant: str, sigma2: float, key: str = "visibility_px"
) -> tuple[float, float, float]:
    """``(rho, low, high)``: Spearman's rho of visibility against θ (negative: it grows as
    θ falls) and the mean visibility at θ <= 25° and at θ >= 65°."""
    theta, vis = series(rows, variant, sigma2, key)
    rho = spearman(theta, vis) if len(vis) > 1 and np.ptp(vis) > 0 else 0.0
    return rho, _mean_or_nan(vis[theta <= 25.0]), _mean_or_nan(vis[theta >= 65.0])


def _mean_or_nan(values: np.ndarray) -> float:
    """The mean, NaN for no value (every case on that side of θ not measurable)."""
    return float(values.mean()) if len(values) else math.nan


def finding3_holds(rows, variant: str, key: str = "visibility_px") -> bool:
    """Visibility of every gentle dent grows as θ falls: Spearman rho below
    :data:`HOLDS_RHO` and the views below 25° at least :data:`HOLDS_GAIN` times those above 65°."""
    for sigma2 in GENTLE:
        rho, low, high = trend(rows, variant, sigma2, key)
        if not (rho < HOLDS_RHO and low >= HOLDS_GAIN * high):
            return False
    return True


# --------------------------------------------------------------------------- verdicts
@dataclass(frozen=True)
class GentleTrend:
    """One gentle dent's trend: ρ(θ, visibility) and the mean visibility below 25° and
    above 65° (NaN where no case there can be read)."""

    sigma2: float
    rho: float
    low: float
    high: float


@dataclass(frozen=True)
class VariantVerdict:
    """Finding 3 for one variant: its label, the gentle dents' trends, whether it holds,
    and the cases left out (not readable) with their statuses."""

    label: str
    trends: tuple[GentleTrend, ...]
    holds: bool
    left_out: int
    statuses: tuple[str, ...]

    @property
    def judged(self) -> bool:
        """Both sides of the θ range can be read for every gentle dent."""
        return all(math.isfinite(t.low) and math.isfinite(t.high) for t in self.trends)


def verdicts(rows, variants: Sequence[Named], key: str = "visibility_px") -> list[VariantVerdict]:
    """Does finding 3 hold for the gentle dents of each variant (visibility grows as θ
    falls: rho < :data:`HOLDS_RHO` and the low views beat the high ones by
    :data:`HOLDS_GAIN`)?"""
    out = []
    for variant in variants:
        trends = tuple(GentleTrend(s2, *trend(rows, variant.key, s2, key)) for s2 in GENTLE)
        left_out = [r for r in rows if r["variant"] == variant.key and not readable(r, key)]
        out.append(
            VariantVerdict(
                variant.label,
                trends,
                finding3_holds(rows, variant.key, key),
                len(left_out),
                tuple(sorted({str(r["status"]) for r in left_out})),
            )
        )
    return out


# --------------------------------------------------------------------------- the answer
def _mean(rows, variant: str, key: str, low: bool, sigma2s=GENTLE) -> float:
    values = [
        float(r[key])
        for r in rows
        if r["variant"] == variant
        and r["sigma2_mm2"] in sigma2s
        and r[key] not in (None, "")
        and (key == "noise_floor_px" or readable(r, key))
        and (r["theta_deg"] <= 25.0 if low else r["theta_deg"] >= 65.0)
    ]
    return float(np.mean(values)) if values else float("nan")


@dataclass(frozen=True)
class Over:
    """The gentle dents' visibility over the noise floor on one side of the θ range, or
    (``ratio`` None) the statuses that make it unreadable."""

    ratio: float | None
    statuses: tuple[str, ...] = ()


@dataclass(frozen=True)
class NoisyVariant:
    """A variant with a sensor: its noise floor above 65° and below 25° (every dent),
    and the gentle dents' visibility over it there."""

    label: str
    floor_high: float
    floor_low: float
    over_high: Over
    over_low: Over


@dataclass(frozen=True)
class Margin:
    """What a low view buys over the noise: the variant whose floor falls most as the
    view grazes (None: none falls by :data:`HOLDS_GAIN`) and its floors above 65° and
    below 25°; the variants whose floors stay (``(key, above, below)``)."""

    worst: str | None
    high: float = math.nan
    low: float = math.nan
    exposed: tuple[tuple[str, float, float], ...] = ()


@dataclass(frozen=True)
class Answer:
    """The answer in numbers: the variants for which finding 3 holds (labels); where
    none does, the ideal mirror's continuous limit of the gentle dents above 65° and
    below 25° and its change in per cent; the variants with a sensor; the margin (None
    without a sensor)."""

    holding: tuple[str, ...]
    ideal_high: float
    ideal_low: float
    ideal_change: float | None
    noisy: tuple[NoisyVariant, ...]
    margin: Margin | None


def answer(rows, variants: Sequence[Named], ideal: str) -> Answer:
    """No contour shift grows; the margin over the noise does (``ideal``: the key of the
    ideal mirror, the paper's model)."""
    holding = tuple(v.label for v in variants if finding3_holds(rows, v.key))
    high = _mean(rows, ideal, "visibility_continuous_px", False)
    low = _mean(rows, ideal, "visibility_continuous_px", True)
    noisy = [
        v
        for v in variants
        if any(r["variant"] == v.key and r["noise_floor_px"] not in (None, "") for r in rows)
    ]
    return Answer(
        holding,
        high,
        low,
        None if holding else 100 * (low / high - 1),
        tuple(_noisy(rows, v) for v in noisy),
        _margin(rows, noisy),
    )


def _noisy(rows, variant: Named) -> NoisyVariant:
    high, low = (_mean(rows, variant.key, "noise_floor_px", b, SIGMA2S) for b in (False, True))
    seen_high, seen_low = (_mean(rows, variant.key, "visibility_px", b) for b in (False, True))
    return NoisyVariant(
        variant.label,
        high,
        low,
        _over(seen_high, high, rows, variant.key, False),
        _over(seen_low, low, rows, variant.key, True),
    )


def _over(visibility: float, floor: float, rows, variant: str, low: bool) -> Over:
    """``visibility / floor``, or why it cannot be read (the statuses of the variant's
    gentle dents on that side of the θ range)."""
    if math.isfinite(visibility) and floor > 0:
        return Over(visibility / floor)
    statuses = sorted(
        {
            str(r["status"])
            for r in rows
            if r["variant"] == variant
            and r["sigma2_mm2"] in GENTLE
            and (r["theta_deg"] <= 25.0 if low else r["theta_deg"] >= 65.0)
            and not readable(r)
        }
    )
    return Over(None, tuple(statuses))


def _margin(rows, noisy: Sequence[Named]) -> Margin | None:
    """What a low viewpoint buys over the noise, from the floors of the variants with a
    sensor above 65° and below 25° (where the exposure is fixed, the dim finish at a
    steep view costs margin; exposed for the scene, it does not)."""
    floors = {
        v.key: (
            _mean(rows, v.key, "noise_floor_px", False, SIGMA2S),
            _mean(rows, v.key, "noise_floor_px", True, SIGMA2S),
        )
        for v in noisy
    }
    if not floors:
        return None
    grows = {key: high / low for key, (high, low) in floors.items() if low > 0}
    worst = max(grows, key=lambda key: grows[key]) if grows else None
    if worst is None or grows[worst] < HOLDS_GAIN:
        return Margin(None)
    exposed = tuple((key, *floors[key]) for key, g in grows.items() if g < HOLDS_GAIN)
    return Margin(worst, *floors[worst], exposed)


# --------------------------------------------------------------------------- tables
@dataclass(frozen=True)
class Cell:
    """A case's visibility, with its status where the case cannot be read."""

    value: float
    status: str | None = None


@dataclass(frozen=True)
class VisibilityTable:
    """One σ²: per variant (key), its visibility at each θ (highest first; None where
    there is no case)."""

    sigma2: float
    thetas: tuple[float, ...]
    variants: tuple[tuple[str, tuple[Cell | None, ...]], ...]


def visibility_tables(rows, variants: Sequence[Named]) -> list[VisibilityTable]:
    thetas = tuple(sorted({r["theta_deg"] for r in rows}, reverse=True))
    out = []
    for sigma2 in sorted({r["sigma2_mm2"] for r in rows}):
        lines = []
        for variant in variants:
            cells = {
                r["theta_deg"]: Cell(r["visibility_px"], None if readable(r) else r.get("status"))
                for r in rows
                if r["variant"] == variant.key and r["sigma2_mm2"] == sigma2
            }
            lines.append((variant.key, tuple(cells.get(t) for t in thetas)))
        out.append(VisibilityTable(sigma2, thetas, tuple(lines)))
    return out


@dataclass(frozen=True)
class MarginTable:
    """A variant with a sensor: its noise floor at each θ (highest first) and each
    gentle dent's visibility over it there (None: a floor of 0, an infinite margin)."""

    label: str
    thetas: tuple[float, ...]
    floors: tuple[float, ...]
    ratios: tuple[tuple[float, tuple[float | None, ...]], ...]


def margin_tables(rows, variants: Sequence[Named]) -> list[MarginTable]:
    """For the variants with a sensor: the noise floor and the gentle dents' visibility
    over it (how far above the noise a contour shift stands), against θ."""
    out = []
    for variant in variants:
        floors = {
            r["theta_deg"]: float(r["noise_floor_px"])
            for r in rows
            if r["variant"] == variant.key and r["noise_floor_px"] not in (None, "")
        }
        if not floors:
            continue
        thetas = tuple(sorted(floors, reverse=True))
        ratios = []
        for sigma2 in GENTLE:
            # every case, measurable or not: a ratio of at most 1 is what "noise" means
            by_theta = {
                t: v
                for measurable in (True, False)
                for t, v in zip(
                    *series(rows, variant.key, sigma2, measurable=measurable), strict=True
                )
            }
            ratios.append(
                (sigma2, tuple(by_theta[t] / floors[t] if floors[t] > 0 else None for t in thetas))
            )
        out.append(
            MarginTable(variant.label, thetas, tuple(floors[t] for t in thetas), tuple(ratios))
        )
    return out


# --------------------------------------------------------------------------- reports
@dataclass(frozen=True)
class Finding3Section:
    """What the paper study's report quotes: the answer and the verdicts on the paper's
    metric."""

    answer: Answer
    verdicts: tuple[VariantVerdict, ...]


@dataclass(frozen=True)
class Finding3Report:
    """The numbers of ``finding3.md``: the image size, the answer, the verdicts on the
    paper's metric and on its continuous limit, the visibility tables, the noise floors
    and the rules' thresholds."""

    size: int
    answer: Answer
    verdicts: tuple[VariantVerdict, ...]
    limit_verdicts: tuple[VariantVerdict, ...]
    tables: tuple[VisibilityTable, ...]
    margins: tuple[MarginTable, ...]
    holds_rho: float = HOLDS_RHO
    holds_gain: float = HOLDS_GAIN

    @property
    def pitch_mm(self) -> float:
        """The pixel pitch on the surface: the paper camera's 5 µm at 1024²."""
        return 0.005 * 1024 / self.size

    @property
    def zoom(self) -> float:
        """How many of the paper camera's pixels one pixel of this image spans."""
        return 1024 / self.size


def section(rows, variants: Sequence[Named], ideal: str) -> Finding3Section:
    return Finding3Section(answer(rows, variants, ideal), tuple(verdicts(rows, variants)))


def report(rows, variants: Sequence[Named], size: int, ideal: str) -> Finding3Report:
    return Finding3Report(
        size,
        answer(rows, variants, ideal),
        tuple(verdicts(rows, variants)),
        tuple(verdicts(rows, variants, "visibility_continuous_px")),
        tuple(visibility_tables(rows, variants)),
        tuple(margin_tables(rows, variants)),
    )
