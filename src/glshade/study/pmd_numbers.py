"""The paper's question answered for a phase-measuring station, beside the paper's own
instrument: the numbers of ``pmd_report.md`` (plain values; the template
``templates/pmd_report.md.j2`` words them, :mod:`glshade.study.pmd_findings` renders it).

Each case of the PMD study (``pmd_results.csv``) is paired with the same case of the
stripe study (``results.csv``). The numbers: the θ a PMD station is best placed at per
(surface, σ², dmax), by SNR and by depth error, beside the paper metric's; where the
stripe map folds and the paper's metric is capped, whether the PMD shift follows its
closed form ``2 α_max (De + σ cos θ) · G`` (``G`` the curved base's factor,
:func:`glshade.metrics.physics.pmd_shift_mm`; a case whose law is marked ``grazing`` is
left out of that comparison); whether the decoded noise follows
``periods[0]/(2π) · sqrt(2/N) · σ_I / B``; the paper's findings 1-5 judged for both
instruments (:func:`glshade.study.findings_numbers.evaluate`); and every case side by
side. A number whose status is not ``ok`` is never a plain number here (a
:class:`Reading` carries the status instead), and no verdict or advice rests on it: those
cases are counted.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

from glshade.instruments.pmd.status import pmd_concerns
from glshade.metrics.physics import pmd_shift_law_check
from glshade.metrics.status import concerns
from glshade.study import findings_numbers as findings
from glshade.study.findings_numbers import CLASSES, NEAR_BEST, Scale, Verdict
from glshade.study.formats import finite
from glshade.study.plan import surface_label
from glshade.study.status import STATUS_TEXT, excluded_sentence, is_measurable, status_of

#: The PMD columns judged as the paper's findings judge visibility, and their names.
PMD_METRICS = {"pmd_snr": "PMD SNR", "pmd_shift_mm": "PMD shift"}
PMD_SCALES = {
    "pmd_snr": Scale(unit="", mean="{:.0f}", value="{:.0f}"),
    "pmd_shift_mm": Scale(unit=" mm", mean="{:.3f}", value="{:.3f}"),
}
PAPER_METRIC = {"visibility_px": "paper metric"}
#: What each status other than ``ok`` means for a PMD case, in the report's words.
PMD_STATUS_TEXT = {
    **STATUS_TEXT,
    "unresolved": "fringes averaged out by the pixels",
    "noise": "shift lost in the sensor's noise, or the dent's pixels fail to unwrap",
}
#: A reconstructed depth within this share of dmax counts as measured.
DEPTH_TOLERANCE = 0.05
#: The PMD shift "follows" its closed form within this share.
LAW_TOLERANCE = 0.05

Point = tuple[str, float, float, float]


def point_of(row: Mapping) -> Point:
    return (
        str(row["surface"]),
        float(row["theta_deg"]),
        float(row["sigma2_mm2"]),
        float(row["dmax_mm"]),
    )


@dataclass(frozen=True)
class Pair:
    """One case measured by both instruments: its PMD row and its stripe row (None
    where the stripe study has no such case), and whether the PMD shift's closed form
    holds for it (``law``: ``ok``, or ``grazing``:
    :func:`~glshade.metrics.physics.pmd_shift_law_check`)."""

    pmd: Mapping
    paper: Mapping | None
    law: str = "ok"

    @property
    def law_holds(self) -> bool:
        return self.law == "ok"

    @property
    def point(self) -> Point:
        return point_of(self.pmd)

    @property
    def folds(self) -> bool:
        """The stripe map folds here: the fold law's ratio is above 1 (``results.csv``)."""
        ratio = self.paper.get("fold_ratio") if self.paper is not None else None
        return ratio is not None and float(ratio) > 1.0


def pair_rows(pmd_rows: Sequence[Mapping], paper_rows: Sequence[Mapping], plan=None) -> list[Pair]:
    """Every PMD row with the stripe row of the same case, in the PMD rows' order; with
    the study's ``plan``, each with whether its shift law holds (:func:`law_status`)."""
    paper = {point_of(r): r for r in paper_rows}
    return [
        Pair(r, paper.get(point_of(r)), law_status(plan, point_of(r)) if plan else "ok")
        for r in pmd_rows
    ]


def law_status(plan, point: Point) -> str:
    """Whether the PMD shift's closed form holds for the case at ``point`` of ``plan``
    (``ok`` or ``grazing``, :func:`~glshade.metrics.physics.pmd_shift_law_check`; ``ok``
    for a surface the plan does not hold)."""
    surface, theta, sigma2, dmax = point
    named = {surface_label(s): s for s in plan.surfaces}
    if surface not in named:
        return "ok"
    return pmd_shift_law_check(plan.scene(named[surface], theta, sigma2, dmax)).status


def judged_rows(pairs: Sequence[Pair]) -> list[dict]:
    """The PMD rows as the verdicts read them: each with ``folded`` from the stripe study
    (so a trend's headline says where the stripe map folds)."""
    return [
        {**dict(p.pmd), "folded": bool(p.paper.get("folded")) if p.paper is not None else None}
        for p in pairs
    ]


def depth_error(row: Mapping) -> float:
    """The reconstructed depth's relative error, ``pmd_depth_um / dmax - 1`` (NaN where
    there is none)."""
    depth = row.get("pmd_depth_um")
    truth = 1000.0 * float(row["dmax_mm"])
    if depth is None or not math.isfinite(float(depth)) or truth == 0.0:
        return math.nan
    return float(depth) / truth - 1.0


def fringe_noise(row: Mapping) -> bool:
    """The two noisy decodes of the defect-free scene differ by a fringe somewhere: their
    largest difference exceeds half the finest period, so their std is not noise."""
    floor = _float(row.get("pmd_noise_floor_mm"))
    return not (math.isfinite(floor) and floor < 0.5 * float(row["period_mm"]))


def _float(value) -> float:
    return math.nan if value is None else float(value)


def _ratio(a, b) -> float:
    a, b = _float(a), _float(b)
    return a / b if b and math.isfinite(a) and math.isfinite(b) else math.nan


def _law_error(row: Mapping) -> float:
    return _ratio(row["pmd_shift_mm"], row["pmd_shift_law_mm"]) - 1


# --------------------------------------------------------------------------- readings
@dataclass(frozen=True)
class Reading:
    """One number of a case as a table may show it: its value (None or NaN: there is
    none), or the ``status`` that makes it unreadable (then the value is None)."""

    value: float | None
    status: str | None = None


def pmd_reading(row: Mapping, column: str) -> Reading:
    """A PMD number, or its status where the status makes it unreadable."""
    status = status_of(row)
    return Reading(None, status) if pmd_concerns(status, column) else Reading(row.get(column))


def paper_reading(row: Mapping | None, column: str) -> Reading | None:
    """A stripe-study number, or its status where unreadable (None: the stripe study has
    no such case)."""
    if row is None:
        return None
    status = status_of(row)
    return Reading(None, status) if concerns(status, column) else Reading(row.get(column))


@dataclass(frozen=True)
class CaseLine:
    """One case of both instruments as the tables show it: where it is (the surface's
    label), the fold law's ratio, the stripe study's status (None: not run) and numbers,
    the share of the rays' deflection its continuous limit keeps, the PMD numbers with
    the shift's law (its caveat where it does not hold) and shift / law, the unwrapping
    failures and the PMD status."""

    surface: str
    theta: float
    sigma2: float
    dmax: float
    fold_ratio: float | None
    paper_status: str | None
    paper_px: Reading | None
    limit_px: Reading | None
    deflection_px: Reading | None
    kept: Reading
    shift: Reading
    law: Reading
    law_ratio: Reading
    snr: Reading
    depth: Reading
    unwrap_failures: object
    status: str

    @property
    def dmax_um(self) -> float:
        return 1000 * self.dmax


def case_line(pair: Pair) -> CaseLine:
    r, q = pair.pmd, pair.paper
    ratio = None if q is None or q.get("fold_ratio") is None else float(q["fold_ratio"])
    if q is None:
        kept = Reading(None)
    elif concerns(status_of(q), "deflection_px"):
        kept = Reading(None, status_of(q))
    else:
        kept = Reading(_ratio(q["visibility_continuous_px"], q["deflection_px"]))
    if not pair.law_holds:
        law_ratio = law = Reading(None, pair.law)
    else:
        law = Reading(r["pmd_shift_law_mm"])
        law_ratio = (
            Reading(None, status_of(r))
            if pmd_concerns(status_of(r), "pmd_shift_mm")
            else Reading(_ratio(r["pmd_shift_mm"], r["pmd_shift_law_mm"]))
        )
    return CaseLine(
        surface_label(r["surface"]),
        r["theta_deg"],
        r["sigma2_mm2"],
        r["dmax_mm"],
        ratio,
        None if q is None else status_of(q),
        paper_reading(q, "visibility_px"),
        paper_reading(q, "visibility_continuous_px"),
        paper_reading(q, "deflection_px"),
        kept,
        pmd_reading(r, "pmd_shift_mm"),
        law,
        law_ratio,
        pmd_reading(r, "pmd_snr"),
        pmd_reading(r, "pmd_depth_um"),
        r["unwrap_failures"],
        status_of(r),
    )


# --------------------------------------------------------------------------- best θ
@dataclass(frozen=True)
class Best:
    """One series' best θ by one number: ``theta`` (None where no case is measurable),
    the value there, the θ within reach of it, and how many θ were left out."""

    theta: float | None
    value: float
    near: list[float]
    excluded: int


def best_theta(
    rows: Sequence[Mapping],
    value: Callable[[Mapping], float],
    larger_is_better: bool,
    near: Callable[[float, float], bool],
) -> Best:
    """The θ of ``rows`` (one series) where ``value`` is best, among measurable rows with
    a finite value; ``near(v, best)`` says which other θ come close."""
    kept = [(float(r["theta_deg"]), value(r)) for r in rows if is_measurable(r)]
    kept = [(t, v) for t, v in kept if math.isfinite(v)]
    excluded = len(rows) - len(kept)
    if not kept:
        return Best(None, math.nan, [], excluded)
    pick = max if larger_is_better else min
    theta, top = pick(kept, key=lambda tv: (tv[1], tv[0]))
    return Best(theta, top, sorted((t for t, v in kept if near(v, top)), reverse=True), excluded)


def _series(rows: Sequence[Mapping], surface: str, sigma2: float, dmax: float) -> list[Mapping]:
    return [
        r
        for r in rows
        if r["surface"] == surface and r["sigma2_mm2"] == sigma2 and r["dmax_mm"] == dmax
    ]


def best_by_snr(rows: Sequence[Mapping]) -> Best:
    return best_theta(
        rows, lambda r: _float(r.get("pmd_snr")), True, lambda v, top: v >= NEAR_BEST * top
    )


def best_by_depth(rows: Sequence[Mapping]) -> Best:
    return best_theta(
        rows, lambda r: abs(depth_error(r)), False, lambda v, top: v <= DEPTH_TOLERANCE
    )


def best_by_paper(rows: Sequence[Mapping]) -> Best:
    """The paper metric's best θ: the largest ``visibility_px`` (whole pixels, so ties
    are all listed as ``near``)."""
    return best_theta(rows, lambda r: _float(r.get("visibility_px")), True, lambda v, top: v >= top)


@dataclass(frozen=True)
class Series:
    """One (surface, σ², dmax) series over θ: its best θ by the PMD SNR, by the depth
    error, and by the paper's metric (None: not in the stripe study)."""

    surface: str
    sigma2: float
    dmax: float
    snr: Best
    depth: Best
    paper: Best | None

    @property
    def agree(self) -> bool | None:
        """The PMD's best θ by SNR is one of the paper metric's best θ (None where either
        has none)."""
        if self.snr.theta is None or self.paper is None or self.paper.theta is None:
            return None
        return self.snr.theta in self.paper.near


def series(pairs: Sequence[Pair], plan) -> list[Series]:
    pmd = [p.pmd for p in pairs]
    paper = [p.paper for p in pairs if p.paper is not None]
    out = []
    for surface in plan.surfaces:
        for s2 in plan.sigma2s:
            for d in plan.dmaxs:
                mine, theirs = _series(pmd, surface, s2, d), _series(paper, surface, s2, d)
                out.append(
                    Series(
                        surface,
                        s2,
                        d,
                        best_by_snr(mine),
                        best_by_depth(mine),
                        best_by_paper(theirs) if theirs else None,
                    )
                )
    return out


@dataclass(frozen=True)
class Where:
    """One surface's series by one number: how many series keep every θ near the best,
    of how many, and the others ``(best, σ², dmax)``."""

    surface: str
    every: int
    series: int
    others: tuple[tuple[Best, float, float], ...]


def where(found: Sequence[Series], pick: Callable[[Series], Best], plan) -> list[Where]:
    """Per surface: in how many series the θ near the best (by ``pick``) are all the
    study's θ, and the other series."""
    out = []
    for surface in plan.surfaces:
        mine = [one for one in found if one.surface == surface]
        every = [
            one
            for one in mine
            if pick(one).theta is not None and len(pick(one).near) == len(plan.thetas)
        ]
        others = tuple((pick(one), one.sigma2, one.dmax) for one in mine if one not in every)
        out.append(Where(surface_label(surface), len(every), len(mine), others))
    return out


def noise_share(pairs: Sequence[Pair], surface: str) -> list[float]:
    """The noise floor over the shift, per measurable case of ``surface``: how much of a
    case's largest decoded shift noise alone could make (the shift is a maximum over
    pixels, so its SNR carries that much of the noise's own extreme)."""
    return [
        _ratio(p.pmd["pmd_noise_floor_mm"], p.pmd["pmd_shift_mm"])
        for p in pairs
        if p.pmd["surface"] == surface and is_measurable(p.pmd)
    ]


# --------------------------------------------------------------------------- coding per θ
@dataclass(frozen=True)
class Recoded:
    """One surface at one θ, recoded for that θ alone (closed form, not measured): the
    finest period that resolves there (:func:`glshade.study.pmd_plan.finest_period_mm`),
    and the SNR it would give over the study's coding (the noise is proportional to the
    finest period, the shift does not depend on it)."""

    surface: str
    theta: float
    finest_mm: float
    gain: float


def recoded(plan) -> list[Recoded]:
    from glshade.study.pmd_plan import finest_period_mm

    out = []
    for surface in plan.surfaces:
        used = plan.coding(surface)[0]
        for t in plan.thetas:
            scene = plan.cases_plan.scene(surface, t, plan.sigma2s[0], plan.dmaxs[0])
            finest = finest_period_mm([scene])
            out.append(Recoded(surface, t, finest, used / finest))
    return out


@dataclass(frozen=True)
class Recoding:
    """A coding per θ: every surface's (label) recoding at each θ (:func:`recoded`); the
    largest gain (None: none gains), its surface's coding and the θ where it is
    reached."""

    surfaces: tuple[tuple[str, tuple[Recoded, ...]], ...]
    best: Recoded | None
    used_mm: float
    thetas: tuple[float, ...]

    @property
    def changes(self) -> bool:
        """Some surface would be coded otherwise at some θ."""
        return not all(abs(r.gain - 1.0) < 1e-9 for _, found in self.surfaces for r in found)


def recoding(plan) -> Recoding:
    found = recoded(plan)
    surfaces = tuple(
        (surface_label(s), tuple(r for r in found if r.surface == s)) for s in plan.surfaces
    )
    gains = [r for r in found if r.gain > 1.0 + 1e-9]
    if not gains:
        return Recoding(surfaces, None, math.nan, ())
    best = max(gains, key=lambda r: r.gain)
    thetas = sorted(
        {r.theta for r in gains if r.surface == best.surface and r.gain == best.gain},
        reverse=True,
    )
    return Recoding(surfaces, best, plan.coding(best.surface)[0], tuple(thetas))


# --------------------------------------------------------------------------- advice
def _near_best(rows: Sequence[Mapping], surface: str, sigma2s, dmax: float, key: str):
    """The θ at which every σ² of ``sigma2s`` keeps at least :data:`NEAR_BEST` of its
    best ``key`` (measurable rows only)."""
    ok = [r for r in rows if is_measurable(r) and r.get(key) is not None]
    if not any(r["surface"] == surface and r["dmax_mm"] == dmax for r in ok):
        return None
    return findings.best_thetas(ok, surface, sigma2s, dmax, key)


@dataclass(frozen=True)
class Advice:
    """One class of dent on one surface at one depth: the θ the paper's rule keeps (its
    continuous limit), the θ the same rule keeps on the PMD SNR, and the θ that
    reconstruct every dent of the class within :data:`DEPTH_TOLERANCE` (None: no
    measurable case)."""

    surface: str
    label: str
    dmax: float
    paper: list[float] | None
    snr: list[float] | None
    depth: list[float] | None

    @property
    def compared(self) -> bool:
        return None not in (self.paper, self.snr)

    @property
    def differs(self) -> bool:
        return self.compared and self.paper != self.snr


def advice_rows(pairs: Sequence[Pair], plan) -> list[Advice]:
    pmd = [p.pmd for p in pairs]
    paper = [p.paper for p in pairs if p.paper is not None]
    out = []
    for surface in plan.surfaces:
        for label, group in CLASSES:
            present = [v for v in group if v in plan.sigma2s]
            for d in plan.dmaxs if present else ():
                out.append(
                    Advice(
                        surface,
                        label,
                        d,
                        _near_best(paper, surface, present, d, "visibility_continuous_px"),
                        _near_best(pmd, surface, present, d, "pmd_snr"),
                        _depth_thetas(pmd, surface, present, d),
                    )
                )
    return out


def _depth_thetas(rows: Sequence[Mapping], surface: str, sigma2s, dmax: float):
    ok = [
        r
        for r in rows
        if is_measurable(r)
        and r["surface"] == surface
        and r["dmax_mm"] == dmax
        and r["sigma2_mm2"] in sigma2s
    ]
    if not ok:
        return None
    thetas = sorted({r["theta_deg"] for r in ok}, reverse=True)
    return [
        t
        for t in thetas
        if all(abs(depth_error(r)) <= DEPTH_TOLERANCE for r in ok if r["theta_deg"] == t)
        and {r["sigma2_mm2"] for r in ok if r["theta_deg"] == t} == set(sigma2s)
    ]


# --------------------------------------------------------------------------- folds
@dataclass(frozen=True)
class FoldNumbers:
    """What the folded cases show: how many fold, how many both instruments can read,
    the share of the rays' deflection the paper's metric and its limit keep there, the
    PMD shift's relative error against its law there and on the cases that do not fold,
    and how many folded cases follow the law within :data:`LAW_TOLERANCE` or within the
    noise floor."""

    folded: list[Pair]
    both: list[Pair]
    paper_kept: list[float]
    limit_kept: list[float]
    errors: list[float]
    unfolded_errors: list[float]
    within: int
    within_noise: int

    @property
    def abs_errors(self) -> list[float]:
        return [abs(e) for e in self.errors]


def fold_numbers(pairs: Sequence[Pair]) -> FoldNumbers:
    folded = [p for p in pairs if p.folds]
    both = [p for p in folded if is_measurable(p.pmd) and is_measurable(p.paper or {})]
    papers = [p.paper for p in both if p.paper is not None]
    errors = [_law_error(p.pmd) for p in both if p.law_holds]
    return FoldNumbers(
        folded,
        both,
        [_ratio(q["visibility_px"], q["deflection_px"]) for q in papers],
        [_ratio(q["visibility_continuous_px"], q["deflection_px"]) for q in papers],
        errors,
        [
            _law_error(p.pmd)
            for p in pairs
            if not p.folds and p.paper is not None and is_measurable(p.pmd) and p.law_holds
        ],
        sum(abs(e) <= LAW_TOLERANCE for e in finite(errors)),
        sum(
            abs(_float(p.pmd["pmd_shift_mm"]) - _float(p.pmd["pmd_shift_law_mm"]))
            <= _float(p.pmd["pmd_noise_floor_mm"])
            for p in both
            if p.law_holds
        ),
    )


# --------------------------------------------------------------------------- the laws
@dataclass(frozen=True)
class SurfaceLaws:
    """One surface's closed forms against the simulation: the measurable cases whose law
    holds, the shift's relative errors there and how many are within
    :data:`LAW_TOLERANCE` or within the noise floor, the cases whose law is marked
    grazing, the noise over its prediction (cases whose decodes differ by a fringe left
    out) and how many were left out."""

    surface: str
    cases: int
    errors: tuple[float, ...]
    within: int
    within_noise: int
    grazing: int
    noise: tuple[float, ...]
    noise_left_out: int


def surface_laws(pairs: Sequence[Pair]) -> list[SurfaceLaws]:
    out = []
    for surface in dict.fromkeys(p.pmd["surface"] for p in pairs):
        mine = [p for p in pairs if p.pmd["surface"] == surface]
        rows = [p.pmd for p in mine]
        ok = [p.pmd for p in mine if is_measurable(p.pmd) and p.law_holds]
        errors = [_law_error(r) for r in ok]
        clean = [r for r in rows if not fringe_noise(r)]
        out.append(
            SurfaceLaws(
                surface_label(surface),
                len(ok),
                tuple(errors),
                sum(abs(e) <= LAW_TOLERANCE for e in finite(errors)),
                sum(
                    abs(_float(r["pmd_shift_mm"]) - _float(r["pmd_shift_law_mm"]))
                    <= _float(r["pmd_noise_floor_mm"])
                    for r in ok
                ),
                sum(not p.law_holds for p in mine),
                tuple(_ratio(r["pmd_noise_mm"], r["pmd_noise_predicted_mm"]) for r in clean),
                len(rows) - len(clean),
            )
        )
    return out


def worst_law_cases(pairs: Sequence[Pair], count: int = 3) -> list[tuple[float, Mapping]]:
    """The measurable cases whose shift departs most from its law: ``(shift / law - 1,
    row)``, the largest departure first."""
    ok = [p.pmd for p in pairs if is_measurable(p.pmd) and p.law_holds]
    scored = [(_law_error(r), r) for r in ok]
    scored = [(e, r) for e, r in scored if math.isfinite(e)]
    scored.sort(key=lambda er: -abs(er[0]))
    return scored[:count]


def noise_ratios(pairs: Sequence[Pair]) -> list[float]:
    """The decoded noise over its prediction, per case whose decodes do not differ by a
    fringe."""
    clean = [p.pmd for p in pairs if not fringe_noise(p.pmd)]
    return [_ratio(r["pmd_noise_mm"], r["pmd_noise_predicted_mm"]) for r in clean]


# --------------------------------------------------------------------------- findings
@dataclass(frozen=True)
class BothFindings:
    """The paper's findings for both instruments: the verdicts on the paper's metric and
    on the PMD numbers, and the table of them by (finding, scope), each with the verdict
    of the paper's metric, the PMD SNR and the PMD shift (None: none)."""

    paper: tuple[Verdict, ...]
    pmd: tuple[Verdict, ...]
    table: tuple[tuple[int, str, tuple[Verdict | None, ...]], ...]

    def differ(self) -> list[tuple[Verdict, Verdict]]:
        """``(paper, PMD SNR)`` of each (finding, scope) judged for both whose verdicts
        differ."""
        return [(theirs, ours) for theirs, ours in self.both() if theirs.verdict != ours.verdict]

    def both(self) -> list[tuple[Verdict, Verdict]]:
        """``(paper, PMD SNR)`` of each (finding, scope) judged for both."""
        theirs = {(v.finding, v.scope): v for v in self.paper}
        return [
            (theirs[(v.finding, v.scope)], v)
            for v in self.pmd
            if v.metric == PMD_METRICS["pmd_snr"] and (v.finding, v.scope) in theirs
        ]


def both_findings(pairs: Sequence[Pair]) -> BothFindings:
    paper = findings.evaluate([p.paper for p in pairs if p.paper is not None], PAPER_METRIC)
    pmd = findings.evaluate(judged_rows(pairs), PMD_METRICS, PMD_SCALES)
    found = {(v.finding, v.scope, v.metric): v for v in paper + pmd}
    scopes = sorted(dict.fromkeys((v.finding, v.scope) for v in paper + pmd), key=lambda fs: fs[0])
    names = (*PAPER_METRIC.values(), *PMD_METRICS.values())
    table = tuple(
        (number, scope, tuple(found.get((number, scope, name)) for name in names))
        for number, scope in scopes
    )
    return BothFindings(tuple(paper), tuple(pmd), table)


# --------------------------------------------------------------------------- depth
@dataclass(frozen=True)
class DepthRow:
    """One surface's reconstructed depths: per θ of the study, the measurable cases'
    |relative error| and how many cases were left out; how many are within
    :data:`DEPTH_TOLERANCE` of how many with an error, and the worst case and its
    error (None: none)."""

    surface: str
    thetas: tuple[tuple[tuple[float, ...], int], ...]
    within: int
    count: int
    worst: Mapping | None
    worst_error: float


def depth_rows(pairs: Sequence[Pair], plan) -> list[DepthRow]:
    rows = [p.pmd for p in pairs]
    out = []
    for surface in plan.surfaces:
        cells = []
        for t in plan.thetas:
            at = [r for r in rows if r["surface"] == surface and r["theta_deg"] == t]
            ok = [abs(depth_error(r)) for r in at if is_measurable(r)]
            cells.append((tuple(ok), len(at) - len(ok)))
        ok_rows = [r for r in rows if r["surface"] == surface and is_measurable(r)]
        errors = [(abs(depth_error(r)), r) for r in ok_rows]
        errors = [(e, r) for e, r in errors if math.isfinite(e)]
        worst = max(errors, key=lambda er: er[0])[1] if errors else None
        out.append(
            DepthRow(
                surface_label(surface),
                tuple(cells),
                sum(e <= DEPTH_TOLERANCE for e, _ in errors),
                len(errors),
                worst,
                depth_error(worst) if worst is not None else math.nan,
            )
        )
    return out


# --------------------------------------------------------------------------- the report
@dataclass(frozen=True)
class Station:
    """What was run: the cases, the surfaces (labels), the axes, the image size, the
    stripe study's image size (None: unknown), each surface's coding ``(label,
    periods)``, the plan's chain, decoding settings and screen (plain values), the
    sentences on the cases not measurable ``(instrument, sentence)``, and how many cases
    the stripe study lacks."""

    cases: int
    surfaces: tuple[str, ...]
    thetas: tuple[float, ...]
    sigma2s: tuple[float, ...]
    dmaxs: tuple[float, ...]
    size: int
    paper_size: int | None
    codings: tuple[tuple[str, tuple[float, ...]], ...]
    chain: object
    settings: object
    emitter: object
    excluded: tuple[tuple[str, str], ...]
    missing: int


def station(pairs: Sequence[Pair], plan, paper_size: int | None) -> Station:
    scene = plan.scene(plan.surfaces[0], plan.thetas[0], plan.sigma2s[0], plan.dmaxs[0])
    excluded = []
    for name, rows, texts in (
        ("PMD", [p.pmd for p in pairs], PMD_STATUS_TEXT),
        ("Stripe study", [p.paper for p in pairs if p.paper is not None], STATUS_TEXT),
    ):
        sentence = excluded_sentence(rows, texts)
        if sentence:
            excluded.append((name, sentence))
    return Station(
        len(pairs),
        tuple(surface_label(s) for s in plan.surfaces),
        tuple(plan.thetas),
        tuple(plan.sigma2s),
        tuple(plan.dmaxs),
        plan.size,
        paper_size,
        tuple((surface_label(s), tuple(plan.coding(s))) for s in plan.surfaces),
        plan.chain,
        plan.settings,
        scene.emitter,
        tuple(excluded),
        sum(p.paper is None for p in pairs),
    )


@dataclass(frozen=True)
class RunTime:
    """The seconds the records say each stage took over the cases (they stay with the
    cases), and what this run spent measuring, and on how many cases (None: unknown)."""

    cases: int
    render: float
    decode: float
    heights: float
    seconds: float
    computed: int | None


def run_time(rows: Sequence[Mapping], seconds: float, computed: int | None) -> RunTime:
    render, decode, heights = (
        sum(float(r.get(k) or 0.0) for r in rows) for k in ("render_s", "decode_s", "heights_s")
    )
    return RunTime(len(rows), render, decode, heights, seconds, computed)


@dataclass(frozen=True)
class PmdReport:
    """Every number of ``pmd_report.md``, section by section, and the thresholds it
    states."""

    station: Station
    folds: FoldNumbers
    series: tuple[Series, ...]
    snr_where: tuple[Where, ...]
    depth_where: tuple[Where, ...]
    noise_shares: tuple[tuple[str, tuple[float, ...]], ...]
    recoding: Recoding
    advice: tuple[Advice, ...]
    findings: BothFindings
    noise: tuple[float, ...]
    laws: tuple[SurfaceLaws, ...]
    worst_laws: tuple[tuple[float, Mapping], ...]
    fold_lines: tuple[CaseLine, ...]
    depth: tuple[DepthRow, ...]
    cases: tuple[CaseLine, ...]
    run_time: RunTime | None
    near_best: float = NEAR_BEST
    depth_tolerance: float = DEPTH_TOLERANCE
    law_tolerance: float = LAW_TOLERANCE

    @property
    def judged(self) -> list[bool]:
        """Per series judged by both instruments: the PMD's best θ by SNR is one of the
        paper metric's best θ."""
        return [one.agree for one in self.series if one.agree is not None]


def pmd_report(
    pmd_rows: Sequence[Mapping],
    paper_rows: Sequence[Mapping],
    plan,
    paper_size: int | None,
    seconds: float | None = None,
    computed: int | None = None,
) -> PmdReport:
    """Every number of ``pmd_report.md`` (``seconds``: what the run spent measuring,
    None for a rewrite)."""
    pairs = pair_rows(pmd_rows, paper_rows, plan)
    found = series(pairs, plan)
    folds = fold_numbers(pairs)
    return PmdReport(
        station(pairs, plan, paper_size),
        folds,
        tuple(found),
        tuple(where(found, lambda one: one.snr, plan)),
        tuple(where(found, lambda one: one.depth, plan)),
        tuple((surface_label(s), tuple(noise_share(pairs, s))) for s in plan.surfaces),
        recoding(plan),
        tuple(advice_rows(pairs, plan)),
        both_findings(pairs),
        tuple(noise_ratios(pairs)),
        tuple(surface_laws(pairs)),
        tuple(worst_law_cases(pairs)),
        tuple(case_line(p) for p in folds.folded),
        tuple(depth_rows(pairs, plan)),
        tuple(case_line(p) for p in pairs),
        None if seconds is None else run_time(pmd_rows, seconds, computed),
    )
