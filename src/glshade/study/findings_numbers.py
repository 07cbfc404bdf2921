"""The paper's five findings (its section IV) checked against the study's results, and the
numbers of ``report.md``: plain values, no words (the template
``templates/paper_report.md.j2`` words them; :mod:`glshade.study.findings` renders it).

Each finding gets a verdict per surface (and depth, where the finding is about a fixed
depth): "holds", "partly holds" or "does not hold", from the rules the report prints, with
the numbers behind it. Verdicts are given for the paper's metric and for its continuous
limit. The simulation is never tuned to agree.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from glshade.metrics import physics
from glshade.study.formats import um
from glshade.study.notation import image_size
from glshade.study.plan import case_scene, surface_label
from glshade.study.shapes import FLAT, Shape, shape
from glshade.study.stats import spearman
from glshade.study.status import excluded_sentence, split_measurable

HOLDS, PARTLY, NOT = "holds", "partly holds", "does not hold"
METRICS = {"visibility_px": "paper metric", "visibility_continuous_px": "continuous limit"}
GENTLE = (9.0, 16.0)
STEEP = (1.0, 4.0)
#: Smallest relative change of visibility over the θ range that counts as an effect.
MIN_EFFECT = 0.10
#: A viewpoint "keeps the dent most visible" when it reaches this share of the best θ.
NEAR_BEST = 0.9
#: The classes of dent the advice is given for: their names and σ².
CLASSES = (("steep dents (σ² 1, 4)", STEEP), ("gentle dents (σ² 9, 16)", GENTLE))


@dataclass(frozen=True)
class Thresholds:
    """The numbers the rules of the verdicts state (both reports print the rules)."""

    min_effect: float = MIN_EFFECT
    near_best: float = NEAR_BEST


THRESHOLDS = Thresholds()


@dataclass(frozen=True)
class Scale:
    """How a metric's values read in the verdicts: its unit (`` px``: a space, then the
    unit; ``""`` for a ratio) and the formats of a mean over θ and of one value."""

    unit: str = " px"
    mean: str = "{:.1f}"
    value: str = "{:.2f}"


#: The scale of the paper's metric and its limit (pixels of the image).
PIXELS = Scale()


@dataclass(frozen=True)
class Deeper:
    """Finding 1's numbers: over the (θ, σ²) measured at both depths, how often the deeper
    dent is more and less visible, that share, and the median relative gain."""

    high: float
    low: float
    more: int
    less: int
    cases: int
    share: float
    gain: float


@dataclass(frozen=True)
class Wider:
    """Finding 2's numbers: the mean over θ per σ² (in order), Spearman ρ(σ², mean) and
    the relative change from the smallest σ² to the largest."""

    means: tuple[tuple[float, float], ...]
    rho: float
    change: float
    scale: Scale


@dataclass(frozen=True)
class Trend:
    """One σ²'s θ trend: its verdict, Spearman ρ(θ, visibility) and relative change from
    the highest to the lowest θ measured (the numbers the verdict is decided on), the θ
    range and the values there, and the θ at which the value reaches :data:`NEAR_BEST`
    of its best over θ (the reference the camera advice uses too)."""

    sigma2: float
    verdict: str
    rho: float
    change: float
    theta_high: float
    theta_low: float
    value_high: float
    value_low: float
    near_best: tuple[float, ...]
    scale: Scale
    #: The highest θ at which the stripe map folds (None where it never does).
    folds_from: float | None = None


@dataclass(frozen=True)
class Trends:
    """Findings 3 and 4's numbers: each σ²'s trend, the study's θ (for runs of
    neighbours), and the share of its best that :attr:`Trend.near_best` reaches."""

    trends: tuple[Trend, ...]
    thetas: tuple[float, ...]
    near_best: float = NEAR_BEST

    @property
    def lowest_readable(self) -> bool:
        """The series stops above the study's lowest θ (it could not be read there)."""
        return self.trends[0].theta_low > min(self.thetas)


@dataclass(frozen=True)
class Alike:
    """Finding 5's numbers: the scopes where 3 or 4 do not hold, and of how many."""

    failing: tuple[str, ...]
    scopes: int

    @property
    def holding(self) -> int:
        return self.scopes - len(self.failing)

    @property
    def share(self) -> float:
        """The share of the scopes where both hold."""
        return self.holding / self.scopes


@dataclass(frozen=True)
class Verdict:
    """One finding judged on one scope for one metric, and its numbers."""

    finding: int
    scope: str
    metric: str
    verdict: str
    numbers: Deeper | Wider | Trends | Alike


def _worst(verdicts: list[str]) -> str:
    if all(v == HOLDS for v in verdicts):
        return HOLDS
    if all(v in (HOLDS, PARTLY) for v in verdicts):
        return PARTLY
    return NOT


def table(rows: Sequence[Mapping]) -> dict:
    """The rows by ``(surface, θ, σ², dmax)``."""
    return {(r["surface"], r["theta_deg"], r["sigma2_mm2"], r["dmax_mm"]): r for r in rows}


@dataclass(frozen=True)
class _Grid:
    """The rows of a study as a grid: its axes, and ``value(s, t, v, d)`` of one metric."""

    surfaces: list[str]
    dmaxs: list[float]
    sigma2s: list[float]
    thetas: list[float]
    table: dict
    metric: str
    scale: Scale = PIXELS

    def has(self, s, t, v, d) -> bool:
        return (s, t, v, d) in self.table

    def value(self, s, t, v, d) -> float:
        return self.table[(s, t, v, d)][self.metric]


def evaluate(
    rows: Sequence[Mapping],
    metrics: Mapping[str, str] = METRICS,
    scales: Mapping[str, Scale] | None = None,
) -> list[Verdict]:
    """Every verdict the rows support (a finding needs its σ², depths and ≥ 3 θ). A row is
    a :class:`~glshade.study.store.CaseResult` or any mapping of its columns (the
    functions here read rows by column name). ``metrics``: the columns judged and their
    names in the verdicts (the paper's metric and its limit by default); ``scales``: how
    each reads (pixels by default)."""
    rows, _ = split_measurable(rows)
    out: list[Verdict] = []
    if not rows:
        return out
    axes = [
        list(dict.fromkeys(r[key] for r in rows))
        for key in ("surface", "dmax_mm", "sigma2_mm2", "theta_deg")
    ]
    for metric, metric_name in metrics.items():
        grid = _Grid(
            axes[0],
            sorted(axes[1]),
            sorted(axes[2]),
            sorted(axes[3]),
            table(rows),
            metric,
            (scales or {}).get(metric, PIXELS),
        )
        found = (
            _deeper(grid, metric_name)
            + _wider(grid, metric_name)
            + _theta_trends(grid, metric_name)
        )
        out += found + _alike(grid, metric_name, found)
    return out


def _deeper(g: _Grid, metric_name: str) -> list[Verdict]:
    """Finding 1: a deeper dent is more visible."""
    if len(g.dmaxs) < 2:
        return []
    out = []
    lo, hi = g.dmaxs[0], g.dmaxs[-1]
    for s in g.surfaces:
        pairs = [
            (g.value(s, t, v, hi), g.value(s, t, v, lo))
            for t in g.thetas
            for v in g.sigma2s
            if g.has(s, t, v, hi) and g.has(s, t, v, lo)
        ]
        if not pairs:
            continue
        more = sum(a > b for a, b in pairs)
        less = sum(a < b for a, b in pairs)
        share = more / len(pairs)
        verdict = HOLDS if share >= 0.9 and less == 0 else PARTLY if share >= 0.6 else NOT
        gain = float(np.median([a / b - 1 for a, b in pairs if b > 0] or [0.0]))
        numbers = Deeper(hi, lo, more, less, len(pairs), share, gain)
        out.append(Verdict(1, surface_label(s), metric_name, verdict, numbers))
    return out


def _wider(g: _Grid, metric_name: str) -> list[Verdict]:
    """Finding 2: a larger σ² is less visible overall."""
    if len(g.sigma2s) < 2:
        return []
    out = []
    for s in g.surfaces:
        for d in g.dmaxs:
            kept = [
                (v, float(np.mean(vals)))
                for v in g.sigma2s
                if (vals := [g.value(s, t, v, d) for t in g.thetas if g.has(s, t, v, d)])
            ]
            if len(kept) < 2:
                continue
            sigma2s, means = [v for v, _ in kept], [m for _, m in kept]
            rho = spearman(sigma2s, means)
            strictly = all(a > b for a, b in pairwise(means))
            verdict = HOLDS if strictly else PARTLY if rho <= -0.8 else NOT
            change = means[-1] / means[0] - 1 if means[0] > 0 else 0.0
            numbers = Wider(tuple(kept), rho, change, g.scale)
            out.append(
                Verdict(2, f"{surface_label(s)}, dmax {um(d)}", metric_name, verdict, numbers)
            )
    return out


def _theta_trends(g: _Grid, metric_name: str) -> list[Verdict]:
    """Findings 3 and 4: gentle dents fade, steep ones grow, as θ falls."""
    if len(g.thetas) < 3:
        return []
    out = []
    for number, group, sign in ((3, GENTLE, -1.0), (4, STEEP, 1.0)):
        present = [v for v in group if v in g.sigma2s]
        for s in g.surfaces if present else ():
            for d in g.dmaxs:
                trends = [tr for v in present if (tr := _trend(g, s, v, d, sign)) is not None]
                if not trends:
                    continue
                out.append(
                    Verdict(
                        number,
                        f"{surface_label(s)}, dmax {um(d)}",
                        metric_name,
                        _worst([tr.verdict for tr in trends]),
                        Trends(tuple(trends), tuple(g.thetas)),
                    )
                )
    return out


def _trend(g: _Grid, s: str, v: float, d: float, sign: float) -> Trend | None:
    """One σ²'s verdict on a θ trend of sign ``sign``, and its numbers (None with fewer
    than three θ measured)."""
    ts = [t for t in g.thetas if g.has(s, t, v, d)]
    if len(ts) < 3:
        return None
    vals = [g.value(s, t, v, d) for t in ts]
    rho = spearman(ts, vals)
    high, low = vals[-1], vals[0]  # at the highest and the lowest θ
    change = (low - high) / high if high > 0 else (math.inf if low > 0 else 0.0)
    strength, effect = sign * rho, -sign * change
    if strength >= 0.8 and effect >= MIN_EFFECT:
        verdict = HOLDS
    elif strength >= 0.4 and effect > 0:
        verdict = PARTLY
    else:
        verdict = NOT
    near_best = tuple(sorted(near_best_thetas(dict(zip(ts, vals, strict=True)))))
    folded = [t for t in ts if g.table[(s, t, v, d)].get("folded")]
    return Trend(
        v,
        verdict,
        rho,
        change,
        ts[-1],
        ts[0],
        high,
        low,
        near_best,
        g.scale,
        max(folded) if folded else None,
    )


def _alike(g: _Grid, metric_name: str, found: list[Verdict]) -> list[Verdict]:
    """Finding 5: findings 3 and 4 alike on every surface."""
    three_four = [v for v in found if v.finding in (3, 4)]
    if not three_four or len(g.surfaces) < 2:
        return []
    verdict = _worst([v.verdict for v in three_four])
    failing = sorted({v.scope for v in three_four if v.verdict != HOLDS})
    numbers = Alike(tuple(failing), len({v.scope for v in three_four}))
    scope = ", ".join(surface_label(s) for s in g.surfaces)
    return [Verdict(5, scope, metric_name, verdict, numbers)]


def near_best_thetas(values: Mapping[float, float]) -> set[float]:
    """The θ (keys of ``values``, θ -> visibility) at which the visibility reaches at
    least :data:`NEAR_BEST` of its largest: the one reference of the verdicts and the
    camera advice."""
    top = max(values.values())
    return {t for t, v in values.items() if v >= NEAR_BEST * top}


def best_thetas(
    rows: Sequence[Mapping],
    surface: str,
    sigma2s,
    dmax: float,
    key: str = "visibility_continuous_px",
) -> list[float]:
    """The θ at which every σ² of ``sigma2s`` keeps at least :data:`NEAR_BEST` of its
    largest visibility over θ (at depth ``dmax``)."""
    found = table(rows)
    thetas = sorted({r["theta_deg"] for r in rows})
    keep = set(thetas)
    for s2 in sigma2s:
        values = {
            t: found[(surface, t, s2, dmax)][key] for t in thetas if (surface, t, s2, dmax) in found
        }
        if not values:
            continue
        keep &= near_best_thetas(values)
    return sorted(keep, reverse=True)


def series_changes(rows: Sequence[Mapping], surface: str, unfolded_only: bool) -> list[float]:
    """The continuous limit's relative change from the highest to the lowest θ of every
    (σ², dmax) series of ``surface`` (only series that never fold, if asked)."""
    out = []
    for s2 in sorted({r["sigma2_mm2"] for r in rows}):
        for d in sorted({r["dmax_mm"] for r in rows}):
            line = sorted(
                (
                    r
                    for r in rows
                    if r["surface"] == surface and r["sigma2_mm2"] == s2 and r["dmax_mm"] == d
                ),
                key=lambda r: r["theta_deg"],
            )
            if len(line) < 2 or (unfolded_only and any(r.get("folded") for r in line)):
                continue
            high = line[-1]["visibility_continuous_px"]
            if high > 0:
                out.append(line[0]["visibility_continuous_px"] / high - 1)
    return out


# --------------------------------------------------------------------------- advice
@dataclass(frozen=True)
class ClassAdvice:
    """One class of dent on one surface: per group of depths that share them, the θ at
    which every dent of the class keeps :data:`NEAR_BEST` of its best (continuous limit);
    the fold law's onsets ``(θ, σ², dmax)`` (θ ≥ 90: it folds at every θ); and at the
    lowest θ (``low``) the case whose contours lose most to the fold (None where it does
    not fold)."""

    label: str
    ranges: tuple[tuple[tuple[float, ...], tuple[float, ...]], ...]
    onsets: tuple[tuple[float, float, float], ...]
    low: float
    cap: Mapping | None


@dataclass(frozen=True)
class SurfaceAdvice:
    """One surface: its shape, the continuous limit's changes from the highest to the
    lowest θ (on a flat base: of the series that never fold), whether any case folds on
    it, and the advice per class of dent."""

    shape: Shape
    changes: tuple[float, ...]
    folds: bool
    classes: tuple[ClassAdvice, ...]


@dataclass(frozen=True)
class Advice:
    """Where to put the camera: the measurable θ, each surface's advice, the surfaces'
    labels by kind (flat, concave, convex) and the largest gain of the lowest view over
    the highest (continuous limit)."""

    thetas: tuple[float, ...]
    surfaces: tuple[SurfaceAdvice, ...]
    kinds: Mapping[str, tuple[str, ...]]
    best_gain: float


def advice(rows: Sequence[Mapping]) -> Advice | None:
    """For each surface: what it is and what that does, then for each class of dent the
    θ that keep the dent most visible and the fold law's numbers. Measurable rows only;
    None with fewer than three measurable θ."""
    rows, _ = split_measurable(rows)
    thetas = sorted({r["theta_deg"] for r in rows})
    if len(thetas) < 3:
        return None
    surfaces = list(dict.fromkeys(r["surface"] for r in rows))
    shapes = [shape(rows, s) for s in surfaces]
    kinds: dict[str, tuple[str, ...]] = {}
    for sh in shapes:
        kinds[sh.kind] = (*kinds.get(sh.kind, ()), sh.label)
    gains = [c for s in surfaces for c in series_changes(rows, s, False)]
    return Advice(
        tuple(thetas),
        tuple(_surface_advice(rows, sh) for sh in shapes),
        kinds,
        max(gains, default=0.0),
    )


def _surface_advice(rows: Sequence[Mapping], sh: Shape) -> SurfaceAdvice:
    dmaxs = sorted({r["dmax_mm"] for r in rows})
    sigma2s = sorted({r["sigma2_mm2"] for r in rows})
    classes = []
    for label, group in CLASSES:
        present = [v for v in group if v in sigma2s]
        if not present:
            continue
        by_depth: dict[tuple[float, ...], list[float]] = {}
        for d in dmaxs:
            by_depth.setdefault(tuple(best_thetas(rows, sh.surface, present, d)), []).append(d)
        ranges = tuple((kept, tuple(ds)) for kept, ds in by_depth.items())
        classes.append(ClassAdvice(label, ranges, *_folds(rows, sh.surface, present, dmaxs)))
    return SurfaceAdvice(
        sh,
        tuple(series_changes(rows, sh.surface, unfolded_only=sh.kind == FLAT)),
        any(r["surface"] == sh.surface and r.get("folded") for r in rows),
        tuple(classes),
    )


def _folds(rows: Sequence[Mapping], surface: str, sigma2s, dmaxs):
    """The fold law's onsets of one class of dent, the lowest θ, and the case at the
    lowest view whose contours lose most to a fold (None where it does not fold)."""
    found = table(rows)
    low = min(r["theta_deg"] for r in rows)
    onsets = []
    for s2 in sigma2s:
        for d in dmaxs:
            onset = physics.fold_onset_theta_deg(case_scene(surface, 45.0, s2, d))
            if onset > 0:
                onsets.append((onset, s2, d))
    candidates = [
        found[k] for k in ((surface, low, s2, d) for s2 in sigma2s for d in dmaxs) if k in found
    ]
    worst = max(
        candidates, key=lambda r: r["deflection_px"] - r["visibility_continuous_px"], default=None
    )
    return tuple(onsets), low, worst if worst is not None and worst.get("folded") else None


# --------------------------------------------------------------------------- laws
@dataclass(frozen=True)
class LawAgreement:
    """One surface's closed forms against the simulation: the cases compared, how many
    deflections are within 3 % of the deflection law and visible shifts within 5 % of
    the fold cap law, the largest relative errors, and the case of the worst visible
    shift."""

    surface: str
    cases: int
    deflection_within: int
    deflection_worst: float
    visible_within: int
    visible_worst: float
    worst: Mapping


@dataclass(frozen=True)
class Laws:
    """The laws against the simulation: per surface; the fold law's predicted folds and
    its agreement with the ``folded`` flag; on each magnifying surface (label), the
    deflection law's largest error per θ (highest θ first)."""

    surfaces: tuple[LawAgreement, ...]
    predicted: int
    agree: int
    cases: int
    breaks: tuple[tuple[str, tuple[tuple[float, float], ...]], ...]


def laws(rows: Sequence[Mapping]) -> Laws:
    """Where the closed forms hold and where they break, per surface (measurable rows)."""
    surfaces = list(dict.fromkeys(r["surface"] for r in rows))
    agreements = [a for s in surfaces if (a := _law_agreement(rows, s)) is not None]
    breaks = []
    for surface in surfaces:
        sh = shape(rows, surface)
        if sh.magnifies:
            breaks.append((sh.label, tuple(_law_by_theta(rows, surface))))
    return Laws(
        tuple(agreements),
        sum((r["fold_ratio"] or 0.0) > 1.0 for r in rows),
        sum(((r["fold_ratio"] or 0.0) > 1.0) == r["folded"] for r in rows),
        len(rows),
        tuple(breaks),
    )


def _law_agreement(rows: Sequence[Mapping], surface: str) -> LawAgreement | None:
    pick = [
        r
        for r in rows
        if r["surface"] == surface
        and r["visibility_law_px"] is not None
        and math.isfinite(r["visibility_law_px"])
    ]
    if not pick:
        return None
    d_err = [r["deflection_px"] / r["deflection_law_px"] - 1 for r in pick]
    v_err = [r["visibility_continuous_px"] / r["visibility_law_px"] - 1 for r in pick]
    return LawAgreement(
        surface,
        len(pick),
        sum(abs(e) <= 0.03 for e in d_err),
        max(d_err, key=abs),
        sum(abs(e) <= 0.05 for e in v_err),
        max(v_err, key=abs),
        pick[int(np.argmax(np.abs(v_err)))],
    )


def _law_by_theta(rows: Sequence[Mapping], surface: str) -> list[tuple[float, float]]:
    """The largest deflection error of the law at each θ on one surface."""
    out = []
    for t in sorted({r["theta_deg"] for r in rows if r["surface"] == surface}, reverse=True):
        errs = [
            abs(r["deflection_px"] / r["deflection_law_px"] - 1)
            for r in rows
            if r["surface"] == surface and r["theta_deg"] == t
        ]
        out.append((t, max(errs)))
    return out


# --------------------------------------------------------------------------- the report
@dataclass(frozen=True)
class Setup:
    """What was run: the cases (every row), the surfaces ``(surface, label)``, the
    axes, the image, the metric's settings, and the sentence on the cases that could
    not be measured (None: every case could)."""

    cases: int
    surfaces: tuple[tuple[str, str], ...]
    thetas: tuple[float, ...]
    sigma2s: tuple[float, ...]
    dmaxs: tuple[float, ...]
    width: int
    height: int
    step_mm: float
    threshold: float
    keep_fraction: float
    phases: int
    min_period_px: float
    excluded: str | None


def setup(rows: Sequence[Mapping], plan) -> Setup:
    width, height = image_size(plan)
    metric = plan.metric
    return Setup(
        len(rows),
        tuple((s, surface_label(s)) for s in plan.surfaces),
        tuple(plan.thetas),
        tuple(plan.sigma2s),
        tuple(plan.dmaxs),
        width,
        height,
        metric.step_mm,
        metric.threshold,
        metric.keep_fraction,
        len(metric.phases(2.0)),
        metric.min_period_px,
        excluded_sentence(rows),
    )


@dataclass(frozen=True)
class Notes:
    """Over every row: the largest gap between the paper's metric and its limit, the
    surfaces (labels) where the limit is below a pixel, the largest share of a case's
    kept pixels not resolved, and the cases mostly not resolved and their surfaces."""

    gap: float
    sub_pixel: tuple[str, ...]
    unresolved: float
    mostly: int
    mostly_kinds: tuple[str, ...]


def notes(rows: Sequence[Mapping]) -> Notes:
    mostly = [r for r in rows if r["unresolved_fraction"] > 0.5]
    return Notes(
        max((abs(r["visibility_px"] - r["visibility_continuous_px"]) for r in rows), default=0.0),
        tuple(
            sorted(
                {surface_label(r["surface"]) for r in rows if r["visibility_continuous_px"] < 1.0}
            )
        ),
        max((r["unresolved_fraction"] for r in rows), default=0.0),
        len(mostly),
        tuple(sorted({surface_label(r["surface"]) for r in mostly})),
    )


@dataclass(frozen=True)
class PaperReport:
    """The numbers of ``report.md``: the setup, the verdicts, the advice (None with
    fewer than three measurable θ), the laws against the simulation, the measurable
    cases and those that fold, and the notes."""

    setup: Setup
    verdicts: tuple[Verdict, ...]
    advice: Advice | None
    laws: Laws
    measurable: int
    folded: tuple[Mapping, ...]
    notes: Notes

    @property
    def summary(self) -> tuple[tuple[Verdict, Verdict | None], ...]:
        """Each verdict on the paper's metric beside the same finding and scope's on its
        continuous limit (None where it has none)."""
        paper, limit = METRICS.values()
        found = {(v.finding, v.scope): v for v in self.verdicts if v.metric == limit}
        return tuple(
            (v, found.get((v.finding, v.scope))) for v in self.verdicts if v.metric == paper
        )


def paper_report(rows: Sequence[Mapping], plan) -> PaperReport:
    """Every number of ``report.md``. Rows that are not measurable
    (:func:`glshade.study.status.is_measurable`) are counted, not judged."""
    everything = list(rows)
    ok, _ = split_measurable(everything)
    return PaperReport(
        setup(everything, plan),
        tuple(evaluate(ok)),
        advice(ok),
        laws(ok),
        len(ok),
        tuple(r for r in ok if r["folded"]),
        notes(everything),
    )
