"""A budget's table, its closed-form checks and its figure (docs/budget.md).

An input's **contribution** to a number is the root mean square, over its draws, of the
number's error against the reference (the draws of that input alone); the **total** is
the same over the draws of all inputs at once, and the **root-sum-square** (RSS) of the
contributions is what the total would be for independent inputs acting linearly: the
table states both. An input's **share** is its slope-rms contribution's variance over
the sum of every input's (the RSS's square); the total's row shows the total's variance
over that sum (1 where the inputs add independently and linearly).

The numbers per draw (:func:`glshade.uncertainty.draws.draw_numbers`): the slope map's
error as the magnitude of its two components (``∂d/∂x``, ``∂d/∂z``), as a root mean square
over the pixels measured in both (``slope rms``), the same less the error's uniform tilt
(``slope rms, tilt removed``: each component's mean over those pixels taken out), and at
the true dent centre (``slope at dent``), in µrad; the fitted depth's change (µm); the
fitted centre's shift (mm). The share stays the slope rms's; the summary names the input
that leads once the tilt is removed.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from glshade.files import atomic_write_bytes
from glshade.uncertainty.draws import TOTAL, rms

if TYPE_CHECKING:
    from glshade.uncertainty.checks import ClosedFormCheck
    from glshade.uncertainty.result import BudgetRun

#: The numbers a row of the table holds: (record key, column heading, unit, digits).
NUMBERS = (
    ("slope_rms_urad", "slope rms", "µrad", 1),
    ("slope_rms_tilt_removed_urad", "slope rms, tilt removed", "µrad", 1),
    ("slope_dent_urad", "slope at dent", "µrad", 1),
    ("depth_um", "depth", "µm", 4),
    ("shift_mm", "shift", "mm", 4),
)
#: A closed form below this share of its scale (the slope rms; a micrometre of shift) is
#: taken for 0: no ratio is shown.
NEGLIGIBLE = 0.02
#: The label of the joint draws' row and of the root-sum-square's.
TOTAL_LABEL = "total (all inputs drawn together)"
RSS_LABEL = "root-sum-square of the inputs"


@dataclass(frozen=True)
class Row:
    """One line of the budget: ``label`` (an input's path, :data:`TOTAL_LABEL` or
    :data:`RSS_LABEL`), its σ (as a table shows it, and in ``unit``), the root mean square
    over its draws of each of :data:`NUMBERS` (NaN where no draw has the number), its
    ``share`` of the variance, the draws ``used``, those whose status was not ok and those
    without a fitted dent (``no_fit``: left out of the depth and the shift)."""

    label: str
    sigma: float | None
    sigma_text: str
    unit: str
    values: dict[str, float]
    share: float
    used: int
    not_ok: int
    no_fit: int = 0


def budget_rows(run: BudgetRun) -> list[Row]:
    """The budget's rows: one per input (the file's order), the total, the RSS."""
    by_input: dict[str, list[dict[str, Any]]] = {}
    for draw, record in zip(run.draws, run.records, strict=True):
        by_input.setdefault(draw.input, []).append(record)
    rows = []
    for item in run.spec.inputs:
        records = by_input.get(item.path, [])
        rows.append(_row(item.path, item.sigma, item.sigma_text, item.unit, records))
    variance = sum(
        row.values["slope_rms_urad"] ** 2
        for row in rows
        if math.isfinite(row.values["slope_rms_urad"])
    )
    rows = [
        _with_share(row, row.values["slope_rms_urad"] ** 2 / variance if variance else math.nan)
        for row in rows
    ]
    total = _row(TOTAL_LABEL, None, "all", "", by_input.get(TOTAL, []))
    total = _with_share(
        total, total.values["slope_rms_urad"] ** 2 / variance if variance else math.nan
    )
    rss = {
        key: math.sqrt(sum(row.values[key] ** 2 for row in rows if math.isfinite(row.values[key])))
        for key, *_ in NUMBERS
    }
    return [*rows, total, Row(RSS_LABEL, None, "", "", rss, 1.0 if variance else math.nan, 0, 0)]


def _row(
    label: str, sigma: float | None, text: str, unit: str, records: list[dict[str, Any]]
) -> Row:
    values = {key: rms([record.get(key) for record in records]) for key, *_ in NUMBERS}
    not_ok = sum(1 for record in records if record.get("status") != "ok")
    no_fit = sum(1 for record in records if record.get("depth_um") is None)
    return Row(label, sigma, text, unit, values, math.nan, len(records), not_ok, no_fit)


def _with_share(row: Row, share: float) -> Row:
    from dataclasses import replace

    return replace(row, share=share)


# --------------------------------------------------------------------------- text
def _shown(value: float, digits: int) -> str:
    return "—" if not math.isfinite(value) else f"{value:.{digits}f}"


def table_lines(rows: list[Row]) -> list[str]:
    """The budget as a Markdown table (what ``glshade budget`` prints and budget.md holds)."""
    heading = ["input", "σ", *[f"{name} ({unit})" for _, name, unit, _ in NUMBERS], "share"]
    lines = ["| " + " | ".join(heading) + " |", "|" + "---|" * 2 + "---:|" * (len(heading) - 2)]
    for row in rows:
        cells = [
            row.label if row.label in (TOTAL_LABEL, RSS_LABEL) else f"`{row.label}`",
            row.sigma_text or "",
            *[_shown(row.values[key], digits) for key, _, _, digits in NUMBERS],
            "—" if not math.isfinite(row.share) else f"{100 * row.share:.1f} %",
        ]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def dominant(rows: list[Row], key: str = "slope_rms_urad") -> Row | None:
    """The input of the largest contribution to ``key`` (the slope rms; None where no input
    has one)."""
    inputs = [r for r in rows if r.label not in (TOTAL_LABEL, RSS_LABEL)]
    found = [r for r in inputs if math.isfinite(r.values[key])]
    return max(found, key=lambda r: r.values[key]) if found else None


def summary_lines(run: BudgetRun, rows: list[Row]) -> list[str]:
    """What the table means in a few lines: the reference, the draws, the total against
    the RSS, the dominant input, draws whose status was not ok."""
    ref = run.reference
    depth = ref.get("depth_um")
    lines = [
        f"reference (belief = truth): fitted depth "
        f"{'—' if depth is None else f'{depth:.4f}'} µm, status {ref.get('status')}; "
        f"{run.spec.draws} draws per input and {run.spec.draws} of all inputs together, seed "
        f"{run.spec.seed}",
    ]
    total = next(r for r in rows if r.label == TOTAL_LABEL)
    rss = next(r for r in rows if r.label == RSS_LABEL)
    joint, added = (_shown(r.values["slope_rms_urad"], 1) for r in (total, rss))
    lines.append(
        f"slope rms: total {joint} µrad (all drawn together), root-sum-square of the inputs "
        f"{added} µrad"
    )
    top = dominant(rows)
    if top is not None:
        lines.append(
            f"dominant input: {top.label} ({_shown(top.values['slope_rms_urad'], 1)} µrad slope "
            f"rms, {100 * top.share:.1f} % of the variance)"
        )
    key = "slope_rms_tilt_removed_urad"
    untilted = dominant(rows, key)
    if untilted is not None:
        variance = rss.values[key] ** 2
        share = untilted.values[key] ** 2 / variance if variance else math.nan
        lines.append(
            f"with the uniform tilt removed: total {_shown(total.values[key], 1)} µrad, "
            f"root-sum-square {_shown(rss.values[key], 1)} µrad; dominant input "
            f"{untilted.label} ({_shown(untilted.values[key], 1)} µrad, "
            f"{_shown(100 * share, 1)} % of that variance)"
        )
    for row in rows:
        if row.no_fit:
            lines.append(
                f"{row.label}: {row.no_fit} of {row.used} draws fitted no dent (left out of its "
                "depth and shift)"
            )
    not_ok = sum(r.not_ok for r in rows if r.label != RSS_LABEL)
    if not_ok:
        lines.append(
            f"{not_ok} draws were measured with a status other than ok: their numbers are in "
            "draws.csv"
        )
    return lines


# --------------------------------------------------------------------------- files
def csv_bytes(rows: list[Row]) -> bytes:
    """budget.csv: one row per input, the total and the RSS."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(
        [
            "input", "sigma", "sigma_given", "unit", "slope_rms_urad",
            "slope_rms_tilt_removed_urad", "slope_dent_urad", "depth_um", "shift_mm",
            "variance_share", "draws", "draws_not_ok", "draws_without_fit",
        ]
    )  # fmt: skip
    for row in rows:
        writer.writerow(
            [
                row.label,
                "" if row.sigma is None else repr(row.sigma),
                row.sigma_text,
                row.unit,
                *[_csv(row.values[key]) for key, *_ in NUMBERS],
                _csv(row.share),
                row.used,
                row.not_ok,
                row.no_fit,
            ]
        )
    return out.getvalue().encode()


def draws_csv_bytes(run: BudgetRun) -> bytes:
    """draws.csv: every draw, its belief's offsets and its numbers."""
    from glshade.uncertainty.draws import DRAW_NUMBERS

    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    paths = [item.path for item in run.spec.inputs]
    writer.writerow(["input", "draw", *[f"offset {p}" for p in paths], *DRAW_NUMBERS,
                     "pixels", "status"])  # fmt: skip
    for draw, record in zip(run.draws, run.records, strict=True):
        offsets = dict(draw.offsets)
        writer.writerow(
            [
                draw.input,
                draw.number,
                *[repr(offsets[p]) if p in offsets else "" for p in paths],
                *[_csv(record.get(key)) for key in DRAW_NUMBERS],
                record.get("pixels"),
                record.get("status"),
            ]
        )
    return out.getvalue().encode()


def _csv(value: float | None) -> str:
    return "" if value is None or not math.isfinite(value) else f"{value:.6g}"


def markdown(run: BudgetRun, rows: list[Row], checks: list[ClosedFormCheck]) -> str:
    """budget.md: the table, what it means, and the closed-form checks."""
    scene = run.scene
    lines = [
        "# Uncertainty budget",
        "",
        f"{scene.title()}; {scene.camera.width}x{scene.camera.height} pixels, measured by phase "
        f"measuring; budget file {run.spec.source}.",
        "",
        *table_lines(rows),
        "",
        *[f"- {line}" for line in summary_lines(run, rows)],
        "",
        "Each input's row: the root mean square over its draws (that input's belief drawn, "
        "the truth elsewhere) of the error against the reference; slopes as the magnitude of "
        "(∂d/∂x, ∂d/∂z); tilt removed: the slope error less its mean over the pixels compared "
        "(each component: the uniform tilt a reference flat takes out); share: of the slope "
        "rms's variance (docs/budget.md).",
    ]
    if checks:
        lines += ["", "## Closed-form checks (flat mirror, first order)", ""]
        lines += closed_form_lines(checks)
    return "\n".join(lines) + "\n"


def closed_form_lines(checks: list[ClosedFormCheck]) -> list[str]:
    """The closed-form checks as a Markdown table: the budget's contribution, the closed
    form's at the same draws, and their ratio."""
    lines = [
        "| input | number | budget | closed form | ratio |",
        "|---|---|---:|---:|---:|",
    ]
    for check in checks:
        for name, unit, measured, predicted in check.pairs():
            # a number the closed form puts at (nearly) 0 has no ratio to speak of: it is
            # compared with the slope rms (slopes) or a micrometre (the shift)
            scale = check.predicted[0] if unit == "µrad" else 1e-3
            ratio = (
                _shown(measured / predicted, 3)
                if math.isfinite(predicted) and abs(predicted) > NEGLIGIBLE * scale
                else "(≈ 0)"
            )
            digits = 2 if unit == "µrad" else 4
            lines.append(
                f"| `{check.path}` | {name} ({unit}) | {_shown(measured, digits)} | "
                f"{_shown(predicted, digits)} | {ratio} |"
            )
    return lines


#: The figure's second, lighter bars: a number -> the number whose panel it joins.
BESIDE = {"slope_rms_tilt_removed_urad": "slope_rms_urad"}


def figure_bytes(run: BudgetRun, rows: list[Row]) -> bytes:
    """budget.png: each number's contributions as horizontal bars, the total and the RSS
    as lines (SOFAST's sensitivity plots); the slope rms with the tilt removed as a second,
    lighter bar per input in the slope rms's panel (:data:`BESIDE`)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    inputs = [r for r in rows if r.label not in (TOTAL_LABEL, RSS_LABEL)]
    total = next(r for r in rows if r.label == TOTAL_LABEL)
    rss = next(r for r in rows if r.label == RSS_LABEL)
    height = 1.6 + 0.32 * len(inputs)
    fig, axes = plt.subplots(2, 2, figsize=(11, 2 * height), layout="constrained")
    labels = [f"{r.label} (σ {r.sigma_text})" for r in inputs]
    places = list(range(len(inputs)))[::-1]
    panels = [number for number in NUMBERS if number[0] not in BESIDE]
    for ax, (key, name, unit, _) in zip(axes.ravel(), panels, strict=True):
        lighter = [other for other, joined in BESIDE.items() if joined == key]
        if lighter:  # the panel's bars above, the lighter ones below them
            _bars(ax, places, inputs, key, 0.18, "tab:blue", "with its tilt", 0.36)
            _bars(ax, places, inputs, lighter[0], -0.18, "lightsteelblue", "tilt removed", 0.36)
        else:
            _bars(ax, places, inputs, key, 0.0, "tab:blue", None, 0.7)
        _lines(ax, total, rss, key, "tab:red", "")
        for other in lighter:
            _lines(ax, total, rss, other, "lightcoral", ", tilt removed")
        ax.set_yticks(places, labels if ax in axes[:, 0] else [""] * len(labels), fontsize=8)
        ax.set_xlabel(f"{name} ({unit})")
        ax.legend(fontsize=8, loc="best")
        ax.grid(axis="x", alpha=0.3)
    fig.suptitle(f"Uncertainty budget: {run.scene.title()}", fontsize=10)
    out = io.BytesIO()
    fig.savefig(out, format="png", dpi=110)
    plt.close(fig)
    return out.getvalue()


def _bars(
    ax: Any,
    places: list[int],
    inputs: list[Row],
    key: str,
    offset: float,
    color: str,
    label: str | None,
    height: float,
) -> None:
    values = [r.values[key] if math.isfinite(r.values[key]) else 0.0 for r in inputs]
    ax.barh([p + offset for p in places], values, color=color, height=height, label=label)


def _lines(ax: Any, total: Row, rss: Row, key: str, color: str, what: str) -> None:
    for value, label in ((total.values[key], "total"), (rss.values[key], "RSS")):
        if math.isfinite(value):
            style = "-" if label == "total" else "--"
            ax.axvline(value, color=color, linestyle=style, label=f"{label}{what} {value:.3g}")


def write_outputs(run: BudgetRun) -> list[Row]:
    """budget.csv, budget.md, budget.png and draws.csv in the run's folder, each atomically;
    the rows."""
    from glshade.uncertainty.checks import closed_form_checks

    rows = budget_rows(run)
    checks = closed_form_checks(run)
    folder = run.out_dir
    from glshade.uncertainty.result import CSV, DRAWS_CSV, FIGURE, MARKDOWN

    atomic_write_bytes(folder / CSV, csv_bytes(rows), "--out", within=folder)
    atomic_write_bytes(folder / DRAWS_CSV, draws_csv_bytes(run), "--out", within=folder)
    atomic_write_bytes(
        folder / MARKDOWN, markdown(run, rows, checks).encode(), "--out", within=folder
    )
    atomic_write_bytes(folder / FIGURE, figure_bytes(run, rows), "--out", within=folder)
    return rows
