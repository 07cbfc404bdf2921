"""The paper's question answered for a phase-measuring station, beside the paper's own
instrument: ``pmd_report.md``.

Each case of the PMD study (``pmd_results.csv``) is paired with the same case of the
stripe study (``results.csv``). The report gives, with its numbers: the θ a PMD station is
best placed at per (surface, σ², dmax), by SNR and by depth error, beside the paper
metric's; where the stripe map folds and the paper's metric is capped, whether the PMD
shift follows its closed form ``2 α_max (De + σ cos θ) · G`` (``G`` the curved base's
factor, :func:`glshade.metrics.physics.pmd_shift_mm`; a case whose law is marked
``grazing`` is left out of that comparison); whether the decoded noise follows
``periods[0]/(2π) · sqrt(2/N) · σ_I / B``; the paper's findings 1-5 judged for both
instruments (:func:`glshade.study.findings.evaluate`); and every case side by side. A
number whose status is not ``ok`` is never shown as a plain number, and no verdict or
advice rests on it: those cases are counted.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from glshade.files import atomic_write_bytes
from glshade.measure.pmd import pmd_concerns
from glshade.metrics.physics import pmd_shift_law_check
from glshade.metrics.status import concerns
from glshade.study import findings
from glshade.study.escape import markdown_text
from glshade.study.findings import CLASSES, FINDING_TEXT, NEAR_BEST, RULES, Scale, um
from glshade.study.plan import surface_label
from glshade.study.pmd_store import REPORT_NAME
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


def law_cell(pair: Pair, fmt: str = "{:.4f}") -> str:
    """The shift law as a table shows it: the number, or its status where it does not
    hold."""
    return _num(pair.pmd["pmd_shift_law_mm"], fmt) if pair.law_holds else f"*{pair.law}*"


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


# --------------------------------------------------------------------------- cells
def pmd_cell(row: Mapping, column: str, fmt: str = "{:.3g}") -> str:
    """A PMD number as a table shows it: the number, ``—`` where there is none, or its
    status where the status makes it unreadable."""
    status = status_of(row)
    if pmd_concerns(status, column):
        return f"*{markdown_text(status)}*"
    value = row.get(column)
    return "—" if value is None or not math.isfinite(float(value)) else fmt.format(value)


def paper_cell(row: Mapping | None, column: str, fmt: str = "{:g}") -> str:
    """A stripe-study number as a table shows it, with its status where unreadable."""
    if row is None:
        return "not run"
    status = status_of(row)
    if concerns(status, column):
        return f"*{markdown_text(status)}*"
    value = row.get(column)
    return "—" if value is None or not math.isfinite(float(value)) else fmt.format(value)


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


def _float(value) -> float:
    return math.nan if value is None else float(value)


# --------------------------------------------------------------------------- report
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
    findings for both instruments, the depths, the figures and every case."""
    pairs = pair_rows(pmd_rows, paper_rows, plan)
    lines = _opening(pairs, plan, paper_size)
    lines += _in_short(pairs, plan)
    lines += _answer_section(pairs, plan)
    lines += _advice_section(pairs, plan)
    lines += _recoded_section(plan)
    lines += _fold_section(pairs)
    lines += _laws_section(pairs)
    lines += _findings_section(pairs)
    lines += _depth_section(pairs, plan)
    lines += ["## Figures", "", *[f"![{p.stem}]({p.name})" for p in figures], ""]
    lines += _cases_section(pairs)
    if seconds is not None:
        lines += ["## Run time", "", _run_time(pmd_rows, seconds, computed), ""]
    path = Path(out_dir) / REPORT_NAME
    atomic_write_bytes(path, ("\n".join(lines) + "\n").encode(), within=path.parent)
    return path


def _run_time(rows: Sequence[Mapping], seconds: float, computed: int | None) -> str:
    """The seconds the records say each stage took (they stay with the cases), and what
    this run spent measuring."""
    spent = {k: sum(float(r.get(k) or 0.0) for r in rows) for k in ("render_s", "decode_s")}
    heights = sum(float(r.get("heights_s") or 0.0) for r in rows)
    stages = (
        f"Over the {len(rows)} cases' records: render {spent['render_s']:.0f} s, record and "
        f"decode {spent['decode_s']:.0f} s, slopes and heights {heights:.0f} s (the "
        "defect-free analyses not included)."
    )
    if computed == 0:
        return f"{stages} This run measured no case: every case was resumed from its file."
    done = f" ({computed} cases)" if computed is not None else ""
    return f"{stages} This run spent {seconds:.0f} s measuring{done}, analyses included."


def _opening(pairs: Sequence[Pair], plan, paper_size: int | None) -> list[str]:
    chain, settings = plan.chain, plan.settings
    scene = plan.scene(plan.surfaces[0], plan.thetas[0], plan.sigma2s[0], plan.dmaxs[0])
    em = scene.emitter
    codings = "; ".join(
        f"{surface_label(s)}: {', '.join(f'{p:g}' for p in plan.coding(s))} mm"
        for s in plan.surfaces
    )
    size = plan.size
    paper_note = (
        "the stripe study's numbers come from `results.csv` in this directory"
        + (f", measured at {paper_size}×{paper_size} pixels" if paper_size else "")
        + " (its report: `report.md`)"
    )
    lines = [
        "# glshade: the paper's study under phase-measuring deflectometry",
        "",
        (
            f"{len(pairs)} cases: surfaces {', '.join(surface_label(s) for s in plan.surfaces)};"
            f" θ {', '.join(f'{t:g}' for t in plan.thetas)}°; σ² "
            f"{', '.join(f'{v:g}' for v in plan.sigma2s)} mm²; dmax "
            f"{', '.join(um(d) for d in plan.dmaxs)}. Each measured by a PMD station on the "
            f"paper's screen (300 × 300 mm at 256 mm) and camera, images of {size}×{size} "
            f"pixels; {paper_note}."
        ),
        "",
        "**The station.** "
        f"Sinusoidal fringes in both directions (u and v), {chain.shifts} phase steps per "
        f"period, periods (finest first) {codings}; the coarsest spans the screen. Screen: "
        f"offset {em.offset:g}, amplitude {em.amplitude:g}, {em.levels} grey levels, gamma "
        f"{em.gamma:g}. Sensor: full well {chain.full_well_e:g} e⁻, read noise "
        f"{chain.read_noise_e:g} e⁻, {chain.bit_depth} bit, seed {chain.seed}; exposure "
        "auto (the brightest point of the defect-free scene at 0.9 of full scale). "
        f"{chain.supersample}×{chain.supersample} rays per pixel: each pixel integrates its "
        "footprint on the screen, so the modulation falls where the surface compresses the "
        "fringes. Decoding: temporal unwrapping; a pixel is valid where every period's "
        f"modulation is at least {settings.modulation_share:g} of amplitude × the brightest "
        f"response; heights by {settings.heights} integration of the slopes on a grid of "
        f"±{settings.window_sigmas:g} σ, tilt and offset removed beyond "
        f"{settings.plane_sigmas:g} σ, a Gaussian fitted for the depth (docs/pmd.md).",
        "",
        "**The numbers.** `pmd_shift_mm`: the largest move of the decoded screen point the "
        "dent causes, in mm on the screen (not capped by a fold: each pixel is decoded on "
        "its own); `pmd_noise_mm`: the decoded coordinate's noise (std); `pmd_snr` = shift "
        "/ noise: what decides whether a station sees the dent; `pmd_depth_um`: the depth "
        "it reconstructs, against dmax. The paper's metric (`visibility_px`) is in pixels "
        "of its image. Columns: `docs/results.md`.",
        "",
    ]
    for name, rows, texts in (
        ("PMD", [p.pmd for p in pairs], PMD_STATUS_TEXT),
        ("Stripe study", [p.paper for p in pairs if p.paper is not None], STATUS_TEXT),
    ):
        sentence = excluded_sentence(rows, texts)
        if sentence:  # it quotes the rows' reasons: stored text, escaped
            lines += [f"**{name}: {markdown_text(sentence)}**", ""]
    missing = [p for p in pairs if p.paper is None]
    if missing:
        lines += [
            f"**{len(missing)} cases are not in the stripe study's `results.csv`**: they have "
            "no paper metric beside them and are left out of every comparison.",
            "",
        ]
    return lines


def _where_text(found: Sequence[Series], pick: Callable[[Series], Best], plan) -> str:
    """Per surface: in how many series the θ near the best are all the measurable θ, and
    the others' θ (``flat: every θ in 8 of 8 series; sphere: 85–55° (σ² 1, 3 µm), …``)."""
    parts = []
    for surface in plan.surfaces:
        mine = [one for one in found if one.surface == surface]
        every = [
            one for one in mine if pick(one).theta is not None and _all_thetas(pick(one), plan)
        ]
        others = [
            f"{_near_text(pick(one), plan)} (σ² {one.sigma2:g}, {um(one.dmax)})"
            for one in mine
            if one not in every
        ]
        text = f"{surface_label(surface)}: every θ in {len(every)} of {len(mine)} series"
        parts.append(text + (f", else {', '.join(others)}" if others else ""))
    return "; ".join(parts)


def _near_text(best: Best, plan) -> str:
    if best.theta is None:
        return "none measurable"
    return findings.theta_ranges(best.near, plan.thetas)


def _all_thetas(best: Best, plan) -> bool:
    return len(best.near) == len(plan.thetas)


def noise_share(pairs: Sequence[Pair], surface: str) -> list[float]:
    """The noise floor over the shift, per measurable case of ``surface``: how much of a
    case's largest decoded shift noise alone could make (the shift is a maximum over
    pixels, so its SNR carries that much of the noise's own extreme)."""
    return [
        _ratio(p.pmd["pmd_noise_floor_mm"], p.pmd["pmd_shift_mm"])
        for p in pairs
        if p.pmd["surface"] == surface and is_measurable(p.pmd)
    ]


def _noise_text(pairs: Sequence[Pair], plan) -> str:
    parts = [
        f"{surface_label(s)} {_median(noise_share(pairs, s), '{:.0%}')} "
        f"({_span(noise_share(pairs, s), '{:.0%}')})"
        for s in plan.surfaces
    ]
    return (
        "The shift is the largest decoded move over the pixels, so noise alone adds up to "
        "the noise floor to it; the noise floor is, of the shift (median, range): "
        + "; ".join(parts)
        + ". SNR differences between θ smaller than that share are the noise's, not the "
        "geometry's."
    )


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


def _recoded_section(plan) -> list[str]:
    found = recoded(plan)
    if all(abs(r.gain - 1.0) < 1e-9 for r in found):
        return []
    lines = [
        "## A coding per θ (closed form, not measured)",
        "",
        (
            "This study shows each surface one coding at every θ, the one whose finest fringe "
            "resolves at its lowest view. A station that recodes for its own θ could use the "
            "finest period that resolves there (the same rule: the shortest whole mm, at "
            "least 2, spanning 3 pixels). The noise is proportional to the finest period "
            "(the noise law, checked below) and the shift does not depend on it, so the SNR "
            "would "
            "grow by the ratio of the periods:"
        ),
        "",
        "| surface | " + " | ".join(f"θ {t:g}°" for t in plan.thetas) + " |",
        "|---|" + "---:|" * len(plan.thetas),
    ]
    for surface in plan.surfaces:
        mine = [r for r in found if r.surface == surface]
        cells = [f"{r.finest_mm:g} mm, ×{r.gain:.2g}" for r in mine]
        lines.append(f"| {surface_label(surface)} | {' | '.join(cells)} |")
    return lines + [""]


def _in_short(pairs: Sequence[Pair], plan) -> list[str]:
    """The headline numbers of every section below, in a few bullets."""
    f = fold_numbers(pairs)
    found = series(pairs, plan)
    lines = ["## In short", ""]
    if f.both:
        lines.append(
            f"- **Folds.** Where the stripe map folds ({len(f.folded)} cases, {len(f.both)} "
            "measurable by both), the paper's metric keeps a median "
            f"{_median(f.paper_kept, '{:.0%}')} ({_span(f.paper_kept, '{:.0%}')}) of the rays' "
            "deflection; the PMD shift is its closed form within "
            f"{_median([abs(e) for e in f.errors], '{:.1%}')} (median; "
            f"{_span(f.errors, '{:+.1%}')}), {f.within} of {len(f.both)} within "
            f"{LAW_TOLERANCE:.0%}. A fold caps the stripe instrument, not a PMD station."
        )
    judged = [one.agree for one in found if one.agree is not None]
    for what, pick in (
        (f"PMD SNR ≥ {NEAR_BEST:.0%} of its best", lambda one: one.snr),
        (f"depth within {DEPTH_TOLERANCE:.0%}", lambda one: one.depth),
    ):
        lines.append(f"- **Where ({what}).** " + _where_text(found, pick, plan) + ".")
    lines.append(f"- **How finely θ can be ranked.** {_noise_text(pairs, plan)}")
    gains = [r for r in recoded(plan) if r.gain > 1.0 + 1e-9]
    if gains:
        best = max(gains, key=lambda r: r.gain)
        where = sorted(
            {r.theta for r in gains if r.surface == best.surface and r.gain == best.gain},
            reverse=True,
        )
        lines.append(
            f"- **A coding per θ** (closed form): on the {surface_label(best.surface)} a "
            f"{best.finest_mm:g} mm finest fringe resolves at θ "
            f"{findings.theta_ranges(where, plan.thetas)} against this study's "
            f"{plan.coding(best.surface)[0]:g} mm, which would raise its SNR ×{best.gain:.2g} "
            "there; the section below gives every surface and θ."
        )
    lines.append(
        f"- **Best θ.** The single best θ by PMD SNR is one of the paper metric's best θ "
        f"(largest `visibility_px`) in {sum(judged)} of {len(judged)} series; where the SNR "
        "stays within 10 % over many θ its single best is a matter of noise."
    )
    changed = [
        a for a in advice_rows(pairs, plan) if None not in (a.paper, a.snr) and a.paper != a.snr
    ]
    compared = [a for a in advice_rows(pairs, plan) if None not in (a.paper, a.snr)]
    if compared:
        ranges = "; ".join(
            f"{surface_label(a.surface)}, {a.label}, {um(a.dmax)}: paper θ "
            f"{_class_thetas(a.paper, plan)}, PMD θ {_class_thetas(a.snr, plan)}"
            for a in changed
        )
        lines.append(
            f"- **Advice.** The θ that keep 90 % of the best differ between the paper's metric "
            f"and the PMD SNR in {len(changed)} of {len(compared)} (surface, class, depth) "
            "scopes" + (f": {ranges}." if changed else ".")
        )
    paper = findings.evaluate([p.paper for p in pairs if p.paper is not None], PAPER_METRIC)
    ours = findings.evaluate(judged_rows(pairs), {"pmd_snr": "PMD SNR"}, PMD_SCALES)
    theirs = {(v.finding, v.scope): v.verdict for v in paper}
    differ = [
        f"{v.finding} ({v.scope}): {theirs[(v.finding, v.scope)]} → {v.verdict}"
        for v in ours
        if (v.finding, v.scope) in theirs and theirs[(v.finding, v.scope)] != v.verdict
    ]
    both = sum((v.finding, v.scope) in theirs for v in ours)
    lines.append(
        f"- **Findings.** Of {both} verdicts given for both instruments, {len(differ)} differ "
        "between the paper's metric and the PMD SNR"
        + (f" (paper → PMD): {'; '.join(differ)}." if differ else ".")
    )
    clean = [p.pmd for p in pairs if not fringe_noise(p.pmd)]
    noise = [_ratio(r["pmd_noise_mm"], r["pmd_noise_predicted_mm"]) for r in clean]
    if _finite(noise):
        lines.append(
            f"- **Noise.** The decoded noise over its prediction: median "
            f"{_median(noise, '{:.3f}')}, {_span(noise, '{:.3f}')} over {len(_finite(noise))} "
            "cases."
        )
    return lines + [""]


def _theta_text(best: Best, fmt: str) -> str:
    if best.theta is None:
        return "none measurable"
    return f"{best.theta:g}° ({fmt.format(best.value)})"


@dataclass(frozen=True)
class Series:
    """One (surface, σ², dmax) series over θ: its best θ by the PMD SNR, by the depth
    error, and by the paper's metric."""

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


def _answer_section(pairs: Sequence[Pair], plan) -> list[str]:
    lines = [
        "## The answer: where a PMD station's camera should be",
        "",
        (
            "Per surface, σ² and depth: the θ of the highest SNR (and the θ that keep at least "
            f"{NEAR_BEST:.0%} of it), the θ of the smallest depth error (and the θ that "
            f"reconstruct the depth within {DEPTH_TOLERANCE:.0%}), beside the θ of the paper "
            "metric's largest `visibility_px` (whole pixels: every tied θ is listed). Cases "
            "whose status is not ok are left out; the last column counts them (PMD / stripes)."
        ),
        "",
        "| surface | σ² | dmax | best θ by PMD SNR | SNR ≥ 90 % of best | best θ by depth error "
        "| depth within 5 % | paper metric's best θ (px) | left out |",
        "|---|---:|---:|---|---|---|---|---|---:|",
    ]
    found = series(pairs, plan)
    for one in found:
        snr, depth, paper = one.snr, one.depth, one.paper
        if paper is None:
            paper_text, left = "not in results.csv", "—"
        elif paper.theta is None:
            paper_text, left = "none measurable", str(paper.excluded)
        else:
            paper_text = f"{findings.theta_ranges(paper.near, plan.thetas)} ({paper.value:g} px)"
            left = str(paper.excluded)
        depth_text = (
            "none measurable" if depth.theta is None else f"{depth.theta:g}° ({depth.value:.1%})"
        )
        lines.append(
            f"| {surface_label(one.surface)} | {one.sigma2:g} | {um(one.dmax)} | "
            f"{_theta_text(snr, '{:.0f}')} | {findings.theta_ranges(snr.near, plan.thetas)} | "
            f"{depth_text} | {findings.theta_ranges(depth.near, plan.thetas)} | {paper_text} | "
            f"{snr.excluded} / {left} |"
        )
    lines += [""]
    judged = [one.agree for one in found if one.agree is not None]
    if judged:
        lines += [
            f"The PMD station's best θ by SNR is one of the paper metric's best θ in "
            f"{sum(judged)} of {len(judged)} series. {_noise_text(pairs, plan)}",
            "",
        ]
    return lines


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


def _advice_section(pairs: Sequence[Pair], plan) -> list[str]:
    """The paper's advice per class of dent beside a PMD station's."""
    lines = [
        "## The advice per class of dent, for both instruments",
        "",
        (
            f"The θ at which every dent of the class keeps at least {NEAR_BEST:.0%} of its "
            "best: the paper's rule on its continuous limit (as `report.md` gives it), and the "
            "same rule on the PMD SNR; and the θ at which every dent of the class is "
            f"reconstructed within {DEPTH_TOLERANCE:.0%} of its depth."
        ),
        "",
        "| surface | class | dmax | paper metric (continuous limit) | PMD SNR | PMD depth "
        "within 5 % |",
        "|---|---|---:|---|---|---|",
    ]
    for a in advice_rows(pairs, plan):
        cells = [_class_thetas(found, plan) for found in (a.paper, a.snr, a.depth)]
        lines.append(
            f"| {surface_label(a.surface)} | {a.label} | {um(a.dmax)} | {' | '.join(cells)} |"
        )
    return lines + [""]


def _class_thetas(found: list[float] | None, plan) -> str:
    if found is None:
        return "—"
    return findings.theta_ranges(found, plan.thetas) if found else "no θ common to the class"


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


def _ratio(a, b) -> float:
    a, b = _float(a), _float(b)
    return a / b if b and math.isfinite(a) and math.isfinite(b) else math.nan


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


def _law_error(row: Mapping) -> float:
    return _ratio(row["pmd_shift_mm"], row["pmd_shift_law_mm"]) - 1


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
        sum(abs(e) <= LAW_TOLERANCE for e in _finite(errors)),
        sum(
            abs(_float(p.pmd["pmd_shift_mm"]) - _float(p.pmd["pmd_shift_law_mm"]))
            <= _float(p.pmd["pmd_noise_floor_mm"])
            for p in both
            if p.law_holds
        ),
    )


def _fold_section(pairs: Sequence[Pair]) -> list[str]:
    lines = ["## Where the stripe map folds: the paper's metric is capped, PMD is not", ""]
    f = fold_numbers(pairs)
    if not f.folded:
        return lines + ["No case of this study folds (fold law, `fold_ratio` ≤ 1 everywhere).", ""]
    lines += [
        (
            f"{len(f.folded)} cases fold (`fold_ratio` > 1 in `results.csv`); {len(f.both)} of "
            "them are measurable by both instruments. There the paper's metric sees only what "
            "the fold leaves of the contours: `visibility_px` is "
            f"{_span(f.paper_kept, '{:.0%}')} of the rays' deflection `deflection_px` (median "
            f"{_median(f.paper_kept, '{:.0%}')}), its continuous limit "
            f"{_span(f.limit_kept, '{:.0%}')} (median {_median(f.limit_kept, '{:.0%}')}). A "
            "PMD station decodes each pixel's screen point on its own, so a fold cannot cap "
            "its shift; against the closed form 2 α_max (De + σ cos θ) · G (`pmd_shift_law_mm`) "
            f"shift / law − 1 is {_span(f.errors, '{:+.1%}')} (median "
            f"{_median(f.errors, '{:+.1%}')}) on these cases: {f.within} of {len(f.both)} "
            f"within {LAW_TOLERANCE:.0%}, {f.within_noise} within the noise floor; on the "
            "measurable cases that do not fold it is "
            f"{_span(f.unfolded_errors, '{:+.1%}')} (median "
            f"{_median(f.unfolded_errors, '{:+.1%}')})."
        ),
        "",
        "| surface | θ | σ² | dmax | fold ratio | paper px | limit px | deflection px | "
        "limit / deflection | PMD shift mm | law mm | shift / law | PMD SNR | depth µm | PMD "
        "status |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|",
    ]
    for p in f.folded:
        r, q = p.pmd, p.paper or {}
        law_ratio = (
            f"{_ratio(r['pmd_shift_mm'], r['pmd_shift_law_mm']):.3f}"
            if not pmd_concerns(status_of(r), "pmd_shift_mm") and p.law_holds
            else f"*{status_of(r) if p.law_holds else p.law}*"
        )
        share = (
            f"{_ratio(q['visibility_continuous_px'], q['deflection_px']):.0%}"
            if not concerns(status_of(q), "deflection_px")
            else f"*{status_of(q)}*"
        )
        lines.append(
            f"| {surface_label(r['surface'])} | {r['theta_deg']:g} | {r['sigma2_mm2']:g} | "
            f"{um(r['dmax_mm'])} | {float(q['fold_ratio']):.2f} | "
            f"{paper_cell(q, 'visibility_px')} | "
            f"{paper_cell(q, 'visibility_continuous_px', '{:.2f}')} | "
            f"{paper_cell(q, 'deflection_px', '{:.2f}')} | {share} | "
            f"{pmd_cell(r, 'pmd_shift_mm', '{:.4f}')} | {law_cell(p)} "
            f"| {law_ratio} | {pmd_cell(r, 'pmd_snr', '{:.0f}')} | "
            f"{pmd_cell(r, 'pmd_depth_um', '{:.3f}')} | {markdown_text(status_of(r))} |"
        )
    return lines + [""]


def _num(value, fmt: str) -> str:
    return "—" if value is None or not math.isfinite(float(value)) else fmt.format(value)


def _finite(values) -> list[float]:
    return [float(v) for v in values if v is not None and math.isfinite(float(v))]


def _span(values, fmt: str) -> str:
    values = _finite(values)
    if not values:
        return "—"
    lo, hi = min(values), max(values)
    return (
        fmt.format(lo)
        if fmt.format(lo) == fmt.format(hi)
        else f"{fmt.format(lo)} to {fmt.format(hi)}"
    )


def _median(values, fmt: str) -> str:
    values = _finite(values)
    return fmt.format(statistics.median(values)) if values else "—"


def _laws_section(pairs: Sequence[Pair]) -> list[str]:
    """The PMD shift against its closed form and the noise against its prediction, per
    surface."""
    lines = [
        "## The closed forms against the PMD simulation",
        "",
        (
            "Shift: `pmd_shift_law_mm` = 2 α_max (De + σ cos θ) · G, α_max = dmax e^(-1/2) / σ "
            "(the dent's steepest slope; a slope α turns the reflected ray by 2 α, which "
            "lands 2 α De away on the screen, the steepest flank σ cos θ farther), G the "
            "factor by which a base curved along the plane of incidence bends it (1 on the "
            "flat plate and the paper's cylinder; docs/physics.md, section 7). Where the "
            "base's horizon falls inside the dent's window the law is marked *grazing* and "
            "left out here. It ignores the noise: the measured shift is the largest decoded "
            "move over the pixels, so noise adds up to the noise floor (`pmd_noise_floor_mm`, "
            "the largest difference of two noisy decodes of the defect-free scene). Noise: "
            "`pmd_noise_predicted_mm` = periods[0] / (2π) · sqrt(2/N) · σ_I / B (σ_I the "
            "sensor's noise at each pixel's mean level, B its modulation), against the "
            "measured `pmd_noise_mm`. Measurable cases only for the shift; the noise is a "
            "number of the defect-free scene and stays readable in every case, but cases "
            "whose two noisy decodes unwrap to different fringes are not noise: they are "
            "counted apart."
        ),
        "",
        "| surface | cases | shift within 5 % of the law | shift / law − 1 (median; range) | "
        "shift − law within the noise floor | law marked grazing | noise: measured / "
        "predicted (median; range) | noise cases left out |",
        "|---|---:|---:|---|---:|---:|---|---:|",
    ]
    for surface in dict.fromkeys(p.pmd["surface"] for p in pairs):
        mine = [p for p in pairs if p.pmd["surface"] == surface]
        rows = [p.pmd for p in mine]
        ok = [p.pmd for p in mine if is_measurable(p.pmd) and p.law_holds]
        errors = [_ratio(r["pmd_shift_mm"], r["pmd_shift_law_mm"]) - 1 for r in ok]
        within = sum(abs(e) <= LAW_TOLERANCE for e in _finite(errors))
        floor = sum(
            abs(_float(r["pmd_shift_mm"]) - _float(r["pmd_shift_law_mm"]))
            <= _float(r["pmd_noise_floor_mm"])
            for r in ok
        )
        clean = [r for r in rows if not fringe_noise(r)]
        noise = [_ratio(r["pmd_noise_mm"], r["pmd_noise_predicted_mm"]) for r in clean]
        grazing = sum(not p.law_holds for p in mine)
        lines.append(
            f"| {surface_label(surface)} | {len(ok)} | {within} | {_median(errors, '{:+.1%}')}; "
            f"{_span(errors, '{:+.1%}')} | {floor} | {grazing} | {_median(noise, '{:.3f}')}; "
            f"{_span(noise, '{:.3f}')} | {len(rows) - len(clean)} |"
        )
    worst = _worst_law_cases(pairs)
    if worst:
        lines += ["", "Where the shift departs most from the law (measurable cases): " + worst]
    return lines + [""]


def fringe_noise(row: Mapping) -> bool:
    """The two noisy decodes of the defect-free scene differ by a fringe somewhere: their
    largest difference exceeds half the finest period, so their std is not noise."""
    floor = _float(row.get("pmd_noise_floor_mm"))
    return not (math.isfinite(floor) and floor < 0.5 * float(row["period_mm"]))


def _worst_law_cases(pairs: Sequence[Pair]) -> str:
    ok = [p.pmd for p in pairs if is_measurable(p.pmd) and p.law_holds]
    scored = [(abs(_ratio(r["pmd_shift_mm"], r["pmd_shift_law_mm"]) - 1), r) for r in ok]
    scored = [(e, r) for e, r in scored if math.isfinite(e)]
    scored.sort(key=lambda er: -er[0])
    return "; ".join(
        f"{surface_label(r['surface'])} θ {r['theta_deg']:g}°, σ² {r['sigma2_mm2']:g}, "
        f"{um(r['dmax_mm'])}: {r['pmd_shift_mm']:.4f} mm against {r['pmd_shift_law_mm']:.4f} "
        f"mm ({_ratio(r['pmd_shift_mm'], r['pmd_shift_law_mm']) - 1:+.1%}; noise floor "
        f"{r['pmd_noise_floor_mm']:.4f} mm)"
        for _, r in scored[:3]
    )


def _findings_section(pairs: Sequence[Pair]) -> list[str]:
    paper_rows = [p.paper for p in pairs if p.paper is not None]
    paper = findings.evaluate(paper_rows, PAPER_METRIC)
    pmd = findings.evaluate(judged_rows(pairs), PMD_METRICS, PMD_SCALES)
    lines = [
        "## The paper's findings, for both instruments",
        "",
        (
            "The rules of `report.md` (below), applied to the paper's metric (`visibility_px` "
            "of the stripe study) and to the PMD station's SNR and shift, over the same cases. "
            "Cases whose status is not ok are left out of each instrument's verdicts (counted "
            "at the top of this report)."
        ),
        "",
        "| finding | scope | paper metric | PMD SNR | PMD shift |",
        "|---|---|---|---|---|",
    ]
    table = {(v.finding, v.scope, v.metric): v.text for v in paper + pmd}
    scopes = list(dict.fromkeys((v.finding, v.scope) for v in paper + pmd))
    for number, scope in sorted(scopes, key=lambda fs: fs[0]):
        cells = [
            table.get((number, scope, name), "—")
            for name in ("paper metric", *PMD_METRICS.values())
        ]
        lines.append(f"| {number} | {scope} | {' | '.join(cells)} |")
    lines += ["", "How the verdicts are decided:", "", *[f"- {rule}" for rule in RULES], ""]
    for number, text in FINDING_TEXT.items():
        mine = [v for v in pmd if v.finding == number]
        if not mine:
            continue
        lines += [
            f"### Finding {number}, PMD: {text}",
            "",
            "| scope | number | verdict | evidence |",
            "|---|---|---|---|",
            *[f"| {v.scope} | {v.metric} | **{v.verdict}** | {v.evidence} |" for v in mine],
            "",
        ]
    return lines


def _depth_section(pairs: Sequence[Pair], plan) -> list[str]:
    rows = [p.pmd for p in pairs]
    lines = [
        "## The reconstructed depth against the true one",
        "",
        (
            "Median |pmd_depth_um / dmax − 1| per surface and θ over its σ² and depths "
            "(measurable cases; in brackets how many were left out); the last columns: the "
            f"cases within {DEPTH_TOLERANCE:.0%} and the worst."
        ),
        "",
        "| surface | " + " | ".join(f"θ {t:g}°" for t in plan.thetas) + " | within 5 % | worst |",
        "|---|" + "---:|" * len(plan.thetas) + "---:|---|",
    ]
    for surface in plan.surfaces:
        cells = []
        for t in plan.thetas:
            at = [r for r in rows if r["surface"] == surface and r["theta_deg"] == t]
            ok = [abs(depth_error(r)) for r in at if is_measurable(r)]
            left = len(at) - len(ok)
            text = _median(ok, "{:.1%}")
            cells.append(text + (f" ({left})" if left else ""))
        ok_rows = [r for r in rows if r["surface"] == surface and is_measurable(r)]
        errors = [(abs(depth_error(r)), r) for r in ok_rows]
        errors = [(e, r) for e, r in errors if math.isfinite(e)]
        within = sum(e <= DEPTH_TOLERANCE for e, _ in errors)
        if errors:
            e, r = max(errors, key=lambda er: er[0])
            worst = (
                f"{depth_error(r):+.1%} (θ {r['theta_deg']:g}°, σ² {r['sigma2_mm2']:g}, "
                f"{um(r['dmax_mm'])})"
            )
        else:
            worst = "—"
        lines.append(
            f"| {surface_label(surface)} | {' | '.join(cells)} | {within} of {len(errors)} | "
            f"{worst} |"
        )
    return lines + [""]


def _cases_section(pairs: Sequence[Pair]) -> list[str]:
    lines = [
        "## Every case, both instruments",
        "",
        (
            "Paper: `visibility_px` (px) and its continuous limit, whether the stripe map "
            "folds (fold ratio). PMD: shift (mm on the screen) and its law, SNR, depth (µm, "
            "true dmax beside it), unwrapping failures, status. A number its status makes "
            "unreadable is replaced by the status in italics, and a law that does not hold "
            "by its caveat (*grazing*: docs/physics.md, section 7); the reasons are in "
            "`pmd_results.csv` and `results.csv`."
        ),
        "",
        "| surface | θ | σ² | dmax µm | paper px | limit px | fold ratio | paper status | PMD "
        "shift mm | law mm | SNR | depth µm | unwrap failures | PMD status |",
        "|---|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|---:|---:|---|",
    ]
    for p in pairs:
        r, q = p.pmd, p.paper
        ratio = "—" if q is None or q.get("fold_ratio") is None else f"{float(q['fold_ratio']):.2f}"
        lines.append(
            f"| {surface_label(r['surface'])} | {r['theta_deg']:g} | {r['sigma2_mm2']:g} | "
            f"{1000 * r['dmax_mm']:g} | {paper_cell(q, 'visibility_px')} | "
            f"{paper_cell(q, 'visibility_continuous_px', '{:.2f}')} | {ratio} | "
            f"{markdown_text(status_of(q)) if q is not None else 'not run'} | "
            f"{pmd_cell(r, 'pmd_shift_mm', '{:.4f}')} | {law_cell(p)} "
            f"| {pmd_cell(r, 'pmd_snr', '{:.0f}')} | {pmd_cell(r, 'pmd_depth_um', '{:.3f}')} | "
            f"{r['unwrap_failures']} | {markdown_text(status_of(r))} |"
        )
    return lines + [""]
