"""The paper's five findings (its section IV) checked against the study's results, advice for an
inspection engineer, and ``report.md``.

Each finding gets a verdict per surface (and depth, where the finding is about a fixed
depth): "holds", "partly holds" or "does not hold", from the rules in :data:`RULES`
(printed in the report), with the numbers behind it. Verdicts are given for the paper's
metric and for its continuous limit. The simulation is never tuned to agree.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from itertools import pairwise
from pathlib import Path

import numpy as np

from glshade.files import atomic_write_bytes
from glshade.metrics import physics
from glshade.study.escape import markdown_text
from glshade.study.notation import image_size, laws_section, symbols_section
from glshade.study.plan import case_scene, surface_label
from glshade.study.shapes import CONCAVE, CONVEX, FLAT, Shape, curvature_text, shape
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

RULES = (
    (
        "1. *Deeper is more visible*: over all (θ, σ²) of a surface, the share of cases where the "
        "5 µm dent is strictly "
        "more visible than the 3 µm one. **holds**: at least 90 % and never less visible; "
        "**partly holds**: at least 60 %."
    ),
    (
        "2. *Larger σ² is less visible overall* (fixed depth): the mean visibility over θ, per "
        "σ². **holds**: it falls "
        "strictly as σ² grows; **partly holds**: Spearman ρ(σ², mean) ≤ -0.8."
    ),
    (
        "3. *Gentle dents (σ² 9, 16) gain from a low viewpoint*: per σ², Spearman ρ(θ, "
        "visibility) and the relative "
        "change from the highest to the lowest θ. **holds**: ρ ≤ -0.8 *and* a gain of at least "
        f"{MIN_EFFECT:.0%}; "
        "**partly holds**: ρ ≤ -0.4 and any gain, however small; both σ² must hold for the scope "
        "to hold. A ranked trend "
        'of a few per cent is not what the paper means by "more visible".'
    ),
    (
        "4. *Steep dents (σ² 1, 4) lose from a low viewpoint*: the same with the signs turned (ρ "
        "≥ 0.8 and a loss of at "
        f"least {MIN_EFFECT:.0%}). For 3 and 4 each verdict shows its ρ and change per σ², "
        "over the θ measured and readable, and the θ at which each σ² reaches at least "
        f"{NEAR_BEST:.0%} of its best visibility over θ (the camera advice's reference)."
    ),
    (
        "5. *3 and 4 hold on flat, cylindrical and spherical surfaces alike*: **holds** when 3 "
        "and 4 hold for every "
        "surface and depth, **partly holds** when each at least partly holds."
    ),
)


def um(dmax_mm: float) -> str:
    """A depth as the report writes it: in µm."""
    return f"{dmax_mm * 1000:g} µm"


@dataclass(frozen=True)
class Verdict:
    finding: int
    scope: str
    metric: str
    verdict: str
    evidence: str
    #: The verdict with its measured difference and where it applies:
    #: "does not hold: σ² 1 -72 %, σ² 4 -22 % (θ 85° → 5°); within 10 % down to θ 35°".
    headline: str = ""

    @property
    def text(self) -> str:
        return self.headline or self.verdict


def _worst(verdicts: list[str]) -> str:
    if all(v == HOLDS for v in verdicts):
        return HOLDS
    if all(v in (HOLDS, PARTLY) for v in verdicts):
        return PARTLY
    return NOT


def _table(rows: Sequence[Mapping]) -> dict:
    return {(r["surface"], r["theta_deg"], r["sigma2_mm2"], r["dmax_mm"]): r for r in rows}


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
            _table(rows),
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
        out.append(
            Verdict(
                1,
                surface_label(s),
                metric_name,
                verdict,
                f"dmax {um(hi)} more visible than {um(lo)} in {more}/{len(pairs)} cases, less in "
                f"{less}",
                f"{verdict}: {um(hi)} more visible in {share:.0%} of the cases "
                f"({more}/{len(pairs)}), by {gain:+.0%} (median)",
            )
        )
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
            mean, unit = g.scale.mean, g.scale.unit
            shown = ", ".join(f"σ² {v:g}: {mean.format(m)}" for v, m in kept)
            change = means[-1] / means[0] - 1 if means[0] > 0 else 0.0
            out.append(
                Verdict(
                    2,
                    f"{surface_label(s)}, dmax {um(d)}",
                    metric_name,
                    verdict,
                    f"mean over θ {shown}{unit}; Spearman ρ = {rho:.2f}",
                    f"{verdict}: σ² {sigma2s[0]:g} → {sigma2s[-1]:g} mean {mean.format(means[0])} "
                    f"→ {mean.format(means[-1])}{unit} ({change:+.0%})",
                )
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
                verdict = _worst([tr.verdict for tr in trends])
                out.append(
                    Verdict(
                        number,
                        f"{surface_label(s)}, dmax {um(d)}",
                        metric_name,
                        verdict,
                        "; ".join(tr.evidence for tr in trends),
                        _trend_headline(verdict, trends, g.thetas),
                    )
                )
    return out


@dataclass(frozen=True)
class _Trend:
    """One σ²'s θ trend: its verdict, evidence, Spearman ρ(θ, visibility) and relative
    change from the highest to the lowest θ measured (the numbers the verdict is decided
    on), the θ range, and the θ at which the value reaches :data:`NEAR_BEST` of its best
    over θ (the reference the camera advice uses too)."""

    sigma2: float
    verdict: str
    evidence: str
    rho: float
    change: float
    theta_high: float
    theta_low: float
    near_best: tuple[float, ...]
    #: The highest θ at which the stripe map folds (None where it never does).
    folds_from: float | None = None


def _trend(g: _Grid, s: str, v: float, d: float, sign: float) -> _Trend | None:
    """One σ²'s verdict on a θ trend of sign ``sign``, and its evidence (None with fewer
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
    fmt, unit = g.scale.value, g.scale.unit
    return _Trend(
        v,
        verdict,
        f"σ² {v:g}: ρ(θ, visibility) = {rho:+.2f}, θ {ts[-1]:g} → {ts[0]:g}: "
        f"{fmt.format(high)} → {fmt.format(low)}{unit} ({change:+.0%})",
        rho,
        change,
        ts[-1],
        ts[0],
        near_best,
        max(folded) if folded else None,
    )


def _trend_headline(verdict: str, trends: list[_Trend], thetas: Sequence[float]) -> str:
    """ "does not hold: σ² 1 -72% (ρ +0.45), σ² 4 -22% (ρ +0.93) (θ 85° → 5°); at least
    90% of its best: σ² 1 at θ 85–35°, σ² 4 at θ 85–55°": the numbers the verdict is
    decided on (:data:`RULES`), and the θ that keep the dent near its best (``thetas``:
    the study's, for runs of neighbours), the reference the camera advice uses."""
    changes = ", ".join(f"σ² {tr.sigma2:g} {tr.change:+.0%} (ρ {tr.rho:+.2f})" for tr in trends)
    where = []
    for tr in trends:
        where.append(f"σ² {tr.sigma2:g} at θ {theta_ranges(set(tr.near_best), thetas)}")
        if tr.folds_from is not None:
            where[-1] += (
                " (folds at every θ)"
                if tr.folds_from == tr.theta_high
                else f" (folds at θ ≤ {tr.folds_from:g}°)"
            )
    span = f"θ {trends[0].theta_high:g}° → {trends[0].theta_low:g}°"
    if trends[0].theta_low > min(thetas):
        span += ", the lowest readable"
    return (
        f"{verdict}: {changes} ({span}); at least {NEAR_BEST:.0%} of its best: {', '.join(where)}"
    )


def _alike(g: _Grid, metric_name: str, found: list[Verdict]) -> list[Verdict]:
    """Finding 5: findings 3 and 4 alike on every surface."""
    three_four = [v for v in found if v.finding in (3, 4)]
    if not three_four or len(g.surfaces) < 2:
        return []
    verdict = _worst([v.verdict for v in three_four])
    failing = sorted({v.scope for v in three_four if v.verdict != HOLDS})
    evidence = (
        "findings 3 and 4 hold everywhere"
        if not failing
        else "not holding in: " + "; ".join(failing)
    )
    scopes = {v.scope for v in three_four}
    holding = len(scopes) - len(failing)
    headline = (
        f"{verdict}: findings 3 and 4 hold in {holding} of {len(scopes)} surface-and-depth "
        f"scopes ({holding / len(scopes):.0%})"
    )
    return [
        Verdict(
            5,
            ", ".join(surface_label(s) for s in g.surfaces),
            metric_name,
            verdict,
            evidence,
            headline,
        )
    ]


FINDING_TEXT = {
    1: "Deeper defects are more visible.",
    2: "At fixed depth, larger σ² is less visible overall.",
    3: "Gentle defects (σ² 9, 16): visibility grows as θ falls (a low viewpoint helps).",
    4: "Steep defects (σ² 1, 4): visibility falls as θ falls (a high viewpoint is better).",
    5: "Findings 3 and 4 hold for flat, cylindrical and spherical surfaces alike.",
}


NEEDS = {
    1: "it needs at least two depths (dmax)",
    2: "it needs at least two σ²",
    3: "it needs at least three θ and σ² 9 or 16",
    4: "it needs at least three θ and σ² 1 or 4",
    5: "it needs findings 3 and 4 on at least two surfaces",
}


# --------------------------------------------------------------------------- advice
def theta_ranges(chosen, plan_thetas) -> str:
    """Some of the study's θ as runs of neighbours in the plan: ``85–45°, 5°``."""
    order = sorted(plan_thetas, reverse=True)
    runs: list[list[float]] = []
    for i, t in enumerate(order):
        if t not in chosen:
            continue
        if runs and order.index(runs[-1][-1]) == i - 1:
            runs[-1].append(t)
        else:
            runs.append([t])
    if not runs:
        return "none"
    return ", ".join(f"{r[0]:g}–{r[-1]:g}°" if len(r) > 1 else f"{r[0]:g}°" for r in runs)


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
    table = _table(rows)
    thetas = sorted({r["theta_deg"] for r in rows})
    keep = set(thetas)
    for s2 in sigma2s:
        values = {
            t: table[(surface, t, s2, dmax)][key] for t in thetas if (surface, t, s2, dmax) in table
        }
        if not values:
            continue
        keep &= near_best_thetas(values)
    return sorted(keep, reverse=True)


def _series_changes(rows: Sequence[Mapping], surface: str, unfolded_only: bool) -> list[float]:
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


def _change_range(changes: list[float]) -> str:
    lo, hi = min(changes), max(changes)
    return f"{lo:+.0%}" if round(lo, 2) == round(hi, 2) else f"{lo:+.0%} to {hi:+.0%}"


def surface_text(rows: Sequence[Mapping], sh: Shape) -> str:
    """What the surface is and what that does to a dent's visibility, from its shape and
    the rows' numbers (laws named as in the report's Laws section)."""
    span = f"from θ {sh.theta_high:g}° to {sh.theta_low:g}°"
    parts = []
    if sh.free_form:
        parts.append(
            "A free-form surface: its curvatures are those at the gaze point, where the dent "
            "sits, and the laws hold there only."
        )
    if sh.kind == FLAT:
        steady = _series_changes(rows, sh.surface, unfolded_only=True)
        measured = (
            f" (measured, continuous limit of the dents that never fold: "
            f"{_change_range(steady)} {span})"
            if steady
            else ""
        )
        parts.append(
            f"Flat along the plane of incidence (κ_t = {curvature_text(sh.kappa_t)}, m = 1 by "
            "the magnification law): by the deflection law a dent that does not fold moves its "
            f"contours as far from any θ{measured}."
        )
    else:
        changes = _series_changes(rows, sh.surface, unfolded_only=False)
        measured = (
            f"; the continuous limit changes by {_change_range(changes)} {span}" if changes else ""
        )
        if sh.kind == CONVEX:
            parts.append(
                f"Convex along the plane of incidence (κ_t = {curvature_text(sh.kappa_t)}): by "
                f"the magnification law it magnifies the stripes, m = {sh.m_high:.3g} at θ "
                f"{sh.theta_high:g}° and {sh.m_low:.3g} at θ {sh.theta_low:g}°, and every shift "
                f"in pixels shrinks by m{measured}."
            )
        else:
            parts.append(
                f"Concave along the plane of incidence (κ_t = {curvature_text(sh.kappa_t)}): by "
                f"the magnification law it shrinks the stripes, m = {sh.m_high:.3g} at θ "
                f"{sh.theta_high:g}° and {sh.m_low:.3g} at θ {sh.theta_low:g}°, so every shift "
                f"in pixels grows by 1/m{measured}; its curvature adds to the dent's in the "
                "fold law."
            )
    folds = [r for r in rows if r["surface"] == sh.surface and r.get("folded")]
    if sh.curved_across and folds:
        parts.append(
            f"Curved across the plane of incidence (κ_s = {curvature_text(sh.kappa_s)}): by "
            "the saddle law a dent that folds keeps more of its shift at low views than on a "
            "plate flat across it."
        )
    if not folds:
        parts.append("No case of this study folds on it (fold law).")
    return " ".join(parts)


def _fold_text(rows: Sequence[Mapping], surface: str, sigma2s, dmaxs) -> str:
    """The fold law's onsets of one class of dent, and the fold cap law's numbers at the
    lowest view."""
    table = _table(rows)
    low = min(r["theta_deg"] for r in rows)
    onsets = []
    for s2 in sigma2s:
        for d in dmaxs:
            onset = physics.fold_onset_theta_deg(case_scene(surface, 45.0, s2, d))
            if onset > 0:
                onsets.append(
                    ("every θ" if onset >= 90 else f"θ < {onset:.1f}°") + f" (σ² {s2:g}, {um(d)})"
                )
    if not onsets:
        return "None of them folds (fold law)."
    text = "Folds (fold law) at " + ", ".join(onsets) + "."
    candidates = [
        table[k] for k in ((surface, low, s2, d) for s2 in sigma2s for d in dmaxs) if k in table
    ]
    worst = max(
        candidates, key=lambda r: r["deflection_px"] - r["visibility_continuous_px"], default=None
    )
    if worst is not None and worst.get("folded"):
        text += (
            f" Fold cap law at θ {low:g}°: the σ² {worst['sigma2_mm2']:g}, "
            f"{um(worst['dmax_mm'])} dent moves the rays by {worst['deflection_px']:.1f} px and "
            f"its contours by {worst['visibility_continuous_px']:.1f} px."
        )
    return text


CLASSES = (("steep dents (σ² 1, 4)", STEEP), ("gentle dents (σ² 9, 16)", GENTLE))


def advice(rows: Sequence[Mapping]) -> list[str]:
    """For each surface: what it is and what that does, then for each class of dent the
    θ that keep the dent most visible and the fold law's numbers. Measurable rows only."""
    rows, _ = split_measurable(rows)
    lines: list[str] = []
    dmaxs = sorted({r["dmax_mm"] for r in rows})
    sigma2s = sorted({r["sigma2_mm2"] for r in rows})
    thetas = {r["theta_deg"] for r in rows}
    if len(thetas) < 3:
        return ["Not given: the advice needs at least three measurable θ."]
    for surface in dict.fromkeys(r["surface"] for r in rows):
        sh = shape(rows, surface)
        named = "" if sh.description == sh.label else f" ({sh.description})"
        lines += [f"**{sh.label}**{named}. {surface_text(rows, sh)}", ""]
        for label, group in CLASSES:
            present = [v for v in group if v in sigma2s]
            if not present:
                continue
            by_depth: dict[str, list[str]] = {}
            for d in dmaxs:
                found = theta_ranges(best_thetas(rows, surface, present, d), thetas)
                by_depth.setdefault(found, []).append(um(d))
            ranges = "; ".join(f"θ {found} ({', '.join(ds)})" for found, ds in by_depth.items())
            lines.append(
                f"- **{sh.label}, {label}**: {ranges}. {_fold_text(rows, surface, present, dmaxs)}"
            )
        lines.append("")
    return lines


def in_short(rows: Sequence[Mapping]) -> str:
    """The advice in one paragraph, by what the surfaces are."""
    rows, _ = split_measurable(rows)
    if len({r["theta_deg"] for r in rows}) < 3:
        return ""
    kinds: dict[str, list[str]] = {}
    for surface in dict.fromkeys(r["surface"] for r in rows):
        sh = shape(rows, surface)
        kinds.setdefault(sh.kind, []).append(sh.label)
    parts = []
    if FLAT in kinds:
        parts.append(
            f"on {', '.join(kinds[FLAT])} (flat along the plane of incidence) a steep dent is "
            "seen best from above its fold onset, a gentle one from anywhere"
        )
    if CONCAVE in kinds:
        parts.append(
            f"on {', '.join(kinds[CONCAVE])} (concave) a lower view enlarges every shift by "
            "1/m, until the dent folds"
        )
    if CONVEX in kinds:
        parts.append(
            f"on {', '.join(kinds[CONVEX])} (convex) from as high as possible, since m shrinks "
            "every shift as the view grazes"
        )
    gains = [
        c
        for s in dict.fromkeys(r["surface"] for r in rows)
        for c in _series_changes(rows, s, False)
    ]
    best = max(gains, default=0.0)
    return (
        "In short: " + "; ".join(parts) + ". The lowest view of this study gains at most "
        f"{best:+.0%} over the highest (continuous limit, any surface and dent)."
    )


def law_summary(rows: Sequence[Mapping]) -> list[str]:
    """Where the closed forms hold and where they break, per surface, in numbers."""
    lines = [
        (
            "| surface | cases | deflection: law within 3 % | worst deflection error | visible "
            "shift: law within 5 % "
            "| worst visible error | worst case |"
        ),
        "|---|---:|---:|---:|---:|---:|---|",
    ]
    for surface in dict.fromkeys(r["surface"] for r in rows):
        pick = [
            r
            for r in rows
            if r["surface"] == surface
            and r["visibility_law_px"] is not None
            and math.isfinite(r["visibility_law_px"])
        ]
        if not pick:
            continue
        d_err = [r["deflection_px"] / r["deflection_law_px"] - 1 for r in pick]
        v_err = [r["visibility_continuous_px"] / r["visibility_law_px"] - 1 for r in pick]
        worst = pick[int(np.argmax(np.abs(v_err)))]
        lines.append(
            f"| {surface} | {len(pick)} | {sum(abs(e) <= 0.03 for e in d_err)} | "
            f"{max(d_err, key=abs):+.1%} "
            f"| {sum(abs(e) <= 0.05 for e in v_err)} | {max(v_err, key=abs):+.1%} "
            f"| θ {worst['theta_deg']:g}°, σ² {worst['sigma2_mm2']:g}, {um(worst['dmax_mm'])} |"
        )
    return lines


def law_by_theta(rows: Sequence[Mapping], surface: str) -> str:
    """The largest deflection error of the law at each θ on one surface."""
    parts = []
    for t in sorted({r["theta_deg"] for r in rows if r["surface"] == surface}, reverse=True):
        errs = [
            abs(r["deflection_px"] / r["deflection_law_px"] - 1)
            for r in rows
            if r["surface"] == surface and r["theta_deg"] == t
        ]
        parts.append(f"θ {t:g}°: {max(errs):.0%}")
    return ", ".join(parts)


# --------------------------------------------------------------------------- report
def write_report(
    rows: Sequence[Mapping], out_dir: Path, plan, figures: list[Path], timings=None
) -> Path:
    """``report.md``: the symbols, the laws, the advice, the verdicts with their rules and
    numbers, the laws against the simulation, the folded cases and the figures. Rows that
    are not measurable (:func:`glshade.study.status.is_measurable`) are counted, not
    judged."""
    everything = list(rows)
    rows, _ = split_measurable(everything)
    verdicts = evaluate(rows)
    lines = _opening(everything, plan)
    lines += symbols_section(rows, plan)
    lines += laws_section()
    lines += _advice_section(rows)
    lines += _findings_sections(verdicts)
    lines += _laws_section(rows)
    lines += _folds_section(rows)
    from glshade.study.finding3 import report_section

    lines += report_section(Path(out_dir))
    lines += _notes(everything, plan)
    lines += ["## Figures", ""]
    lines += [f"![{path.stem}]({path.name})" for path in figures]
    if timings is not None:
        lines += [
            "",
            "## Run time of this run",
            "",
            (
                f"trace {timings.trace:.1f} s, shade {timings.shade:.1f} s, contours "
                f"{timings.contours:.1f} s, "
                f"continuous numbers {timings.continuous:.1f} s, I/O {timings.io:.1f} s, figures "
                f"{timings.figures:.1f} s "
                "(stage sums over the analysing threads or worker processes; cases computed in "
                "this run only)."
            ),
        ]
    path = Path(out_dir) / "report.md"
    atomic_write_bytes(path, ("\n".join(lines) + "\n").encode(), within=path.parent)
    return path


def _named(surface: str) -> str:
    """A surface as the opening lists it: its kind, or its label and the scene file the
    user gave (``saddle (examples/saddle.toml)``)."""
    label = surface_label(surface)
    return label if label == surface else f"{label} (`{surface}`)"


def _opening(rows: Sequence[Mapping], plan) -> list[str]:
    """The report's title, what was run, and which cases could not be measured."""
    width, height = image_size(plan)
    paper = " (the paper's field of view)" if (width, height) == (1024, 1024) else ""
    lines = [
        "# glshade: the paper's study",
        "",
        (
            f"{len(rows)} cases: surfaces {', '.join(_named(s) for s in plan.surfaces)}; "
            f"θ {', '.join(f'{t:g}' for t in plan.thetas)}°; "
            f"σ² {', '.join(f'{v:g}' for v in plan.sigma2s)} mm²; dmax "
            f"{', '.join(um(d) for d in plan.dmaxs)}; images of {width}×{height} pixels{paper}; "
            f"phase step {plan.metric.step_mm:g} mm; threshold {plan.metric.threshold:g}; "
            f"central {plan.metric.keep_fraction:.0%} of the columns kept. Depths are in µm "
            "throughout this report and in the figures' titles and file names; `results.csv` "
            "keeps `dmax_mm`."
        ),
        "",
        (
            "Three numbers per case (`docs/study.md`; every column in `docs/results.md`): the "
            "paper's metric `visibility_px` (whole pixels), its continuous limit "
            "`visibility_continuous_px` (what the paper's metric tends to with a finer phase "
            "step and a finer sensor), and `deflection_px` (how far the rays move). Verdicts "
            "are given for the first two."
        ),
        "",
    ]
    excluded = excluded_sentence(rows)
    if excluded:  # it quotes the rows' reasons: stored text, escaped
        lines += [f"**{markdown_text(excluded)}**", ""]
    return lines


def _advice_section(rows: Sequence[Mapping]) -> list[str]:
    """Where to put the camera, per surface and class of dent."""
    return [
        "## What to do with it: where to put the camera",
        "",
        (
            "For each surface: what it is, and for each class of dent the study's elevations θ "
            f"at which every dent of the class keeps at least {NEAR_BEST:.0%} of its best "
            "visibility (continuous limit), per depth, with the laws that explain it."
        ),
        "",
        *advice(rows),
        in_short(rows),
        "",
    ]


def _findings_sections(verdicts: list[Verdict]) -> list[str]:
    """The verdicts' summary, their rules, and one section per finding."""
    lines = []
    summary = _summary_table(verdicts)
    if summary:
        lines += ["## The paper's findings: summary", "", *summary, ""]
    lines += [
        "## How the verdicts are decided",
        "",
        *[f"- {rule}" for rule in RULES],
        "",
        (
            '"Partly holds" therefore means: the trend is there in rank, or in most cases, but '
            "not strong or not everywhere enough to call it the paper's effect. Each verdict "
            "carries the measured difference it rests on and where it applies."
        ),
        "",
    ]
    for number, text in FINDING_TEXT.items():
        mine = [v for v in verdicts if v.finding == number]
        if not mine:
            lines += [f"## Finding {number}: {text}", "", f"Not evaluated: {NEEDS[number]}.", ""]
            continue
        lines += [
            f"## Finding {number}: {text}",
            "",
            "| scope | metric | verdict | numbers |",
            "|---|---|---|---|",
        ]
        lines += [f"| {v.scope} | {v.metric} | **{v.text}** | {v.evidence} |" for v in mine]
        lines.append("")
    return lines


def _laws_section(rows: Sequence[Mapping]) -> list[str]:
    lines = [
        "## The laws against the simulation",
        "",
        (
            "`deflection_law_px` is the deflection law (D / m), `visibility_law_px` the fold "
            "cap law (the deflection law where nothing folds), `fold_ratio` the fold law's "
            "ratio. `law_vs_simulation.png` plots every case."
        ),
        "",
        *law_summary(rows),
        "",
    ]
    predicted = [r for r in rows if (r["fold_ratio"] or 0.0) > 1.0]
    agree = sum(((r["fold_ratio"] or 0.0) > 1.0) == r["folded"] for r in rows)
    lines.append(
        f"- Fold onset: the fold law predicts {len(predicted)} folded cases; it agrees with the "
        f"`folded` flag in {agree} of {len(rows)} cases."
    )
    for surface in dict.fromkeys(r["surface"] for r in rows):
        sh = shape(rows, surface)
        if not sh.magnifies:
            continue
        lines.append(
            f"- Where the deflection law breaks on {sh.label}: the worst error per θ is "
            f"{law_by_theta(rows, surface)}. At grazing views the dent's flank facing the "
            "camera is seen at the local elevation θ + σ/R, a large change when σ/R is "
            "comparable to θ, and m (∝ 1/sin θ) is then far from its value at the gaze point. "
            "The law holds where σ/R ≪ θ."
        )
    lines.append("")
    return lines


def _folds_section(rows: Sequence[Mapping]) -> list[str]:
    folded = [r for r in rows if r["folded"]]
    lines = ["## Where the stripe map folds", ""]
    if not folded:
        return lines + ["Nowhere.", ""]
    lines += [
        (
            f"{len(folded)} of {len(rows)} cases fold. There the paper's metric measures what a "
            "viewer sees, the band the "
            "fold leaves the contours, not how far the rays move (`deflection_px`); islands cut "
            "off by the fold are counted, "
            "not measured."
        ),
        "",
        "| surface | θ | σ² | dmax | fold ratio | paper px | limit px | law px | deflection px | "
        "islands |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in folded:
        lines.append(
            f"| {surface_label(r['surface'])} | {r['theta_deg']:g} | {r['sigma2_mm2']:g} | "
            f"{um(r['dmax_mm'])} | "
            f"{r['fold_ratio']:.2f} "
            f"| {r['visibility_px']:g} | {r['visibility_continuous_px']:.2f} | "
            f"{r['visibility_law_px']:.2f} "
            f"| {r['deflection_px']:.2f} | {r['islands']} |"
        )
    return lines + [""]


def _notes(rows: Sequence[Mapping], plan) -> list[str]:
    unresolved = max((r["unresolved_fraction"] for r in rows), default=0.0)
    mostly = [r for r in rows if r["unresolved_fraction"] > 0.5]
    gap = max((abs(r["visibility_px"] - r["visibility_continuous_px"]) for r in rows), default=0.0)
    width, height = image_size(plan)
    sub_pixel = sorted(
        {surface_label(r["surface"]) for r in rows if r["visibility_continuous_px"] < 1.0}
    )
    where = (
        f" Where the limit is below a pixel ({', '.join(sub_pixel)}, in some cases), the "
        "paper's metric reads 1 px or 0 px and cannot rank the dents; the limit can."
        if sub_pixel
        else ""
    )
    lines = [
        "## Notes",
        "",
        (
            f"- The paper's metric counts whole pixels at {len(plan.metric.phases(2.0))} phases "
            f"per 2 mm period: it differs from its continuous limit by at most {gap:.2f} px "
            f"here.{where}"
        ),
        (
            "- Pixels where the defect-free stripes span fewer than "
            f"{plan.metric.min_period_px:g} px per period are left out of the contours "
            "(aliasing; see `glshade.metrics.visibility.resolved_mask`); at most "
            f"{unresolved:.1%} of a case's kept pixels were."
        ),
    ]
    if mostly:
        kinds = ", ".join(sorted({surface_label(r["surface"]) for r in mostly}))
        lines.append(
            f"- **{len(mostly)} cases ({kinds}) are mostly not resolved** at "
            f"{width}×{height}: their stripes span fewer than {plan.metric.min_period_px:g} px "
            "per period, so their paper metric measures next to nothing; use a larger --size "
            "(the paper's is 1024)."
        )
    lines += ["- `results.csv` holds every case; the figures below were drawn from it.", ""]
    return lines


def _summary_table(verdicts: list[Verdict]) -> list[str]:
    paper = [v for v in verdicts if v.metric == "paper metric"]
    if not paper:
        return []
    lines = ["| finding | scope | paper metric | continuous limit |", "|---|---|---|---|"]
    limit = {(v.finding, v.scope): v.text for v in verdicts if v.metric == "continuous limit"}
    for v in paper:
        lines.append(
            f"| {v.finding} | {v.scope} | {v.text} | {limit.get((v.finding, v.scope), '—')} |"
        )
    return lines
