"""Figures of the study under phase measuring, in the style of the stripe study's
(:mod:`glshade.study.plots`): the PMD station's SNR and shift against θ beside the paper's
visibility, per surface and depth; the reconstructed depth against the true one; and
the closed forms against the simulation. Cases that are not measurable are drawn as
hollow grey markers; where their value lies off the measurable cases' scale it is drawn
at the axis' edge (the legend says so)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from glshade.instruments.figures import new_figure, save_figure
from glshade.study.plan import surface_label
from glshade.study.plots import (
    NOT_MEASURABLE,
    NOT_MEASURABLE_LABEL,
    legend_outside,
    pixels_label,
    surface_colours,
    surface_name,
)
from glshade.study.pmd_findings import Pair, pair_rows
from glshade.study.status import is_measurable

LAW_FIGURE = "pmd_laws.png"
#: The depth figure's axis: 0 to this many times the true depth.
DEPTH_RANGE = 2.0
DEPTH_FIGURE = "pmd_depth.png"


def visibility_name(surface: str, dmax: float) -> str:
    return f"pmd_visibility_{surface_label(surface)}_dmax{dmax * 1000:g}um.png"


def _value(row: Mapping | None, key: str) -> float:
    value = None if row is None else row.get(key)
    return math.nan if value is None else float(value)


def _limits(values: Sequence[float], floor_zero: bool = True) -> tuple[float, float] | None:
    finite = [v for v in values if math.isfinite(v)]
    if not finite:
        return None
    lo, hi = min(finite), max(finite)
    if floor_zero:
        lo = min(lo, 0.0)
    pad = 0.06 * (hi - lo or abs(hi) or 1.0)
    return lo - pad, hi + pad


def _hollow_handle():
    from matplotlib.lines import Line2D

    return Line2D(
        [], [], color="0.55", marker="o", ls="none", markerfacecolor="none",
        label=f"{NOT_MEASURABLE_LABEL} (clipped to the axis)",
    )  # fmt: skip


def _hollow(ax, xs, ys, limits) -> bool:
    """Draw the cases that are not measurable (hollow grey), clipped to ``limits``;
    True when any was drawn."""
    points = [(x, y) for x, y in zip(xs, ys, strict=True) if math.isfinite(y)]
    if not points:
        return False
    x, y = np.array(points).T
    if limits is not None:
        y = np.clip(y, *limits)
    ax.scatter(x, y, s=40, zorder=3, **NOT_MEASURABLE)
    return True


PANELS = (
    ("pmd", "pmd_snr", None, "PMD SNR (shift / noise)", ""),
    ("pmd", "pmd_shift_mm", "pmd_shift_law_mm", "PMD shift on the screen", "mm on the screen"),
    ("paper", "visibility_px", None, "paper's metric (stripe study)", "px"),
)


def visibility_plot(
    pairs: Sequence[Pair],
    surface: str,
    dmax: float,
    path: Path,
    paper_image: tuple[int, int] | None = None,
) -> None:
    """PMD SNR, PMD shift (dashed: its closed form) and the paper's visibility against
    θ, one colour per σ²; rings mark the cases whose stripe map folds, hollow grey
    markers the cases that are not measurable (left out of the lines)."""
    sel = [p for p in pairs if p.pmd["surface"] == surface and float(p.pmd["dmax_mm"]) == dmax]
    sigma2s = sorted({float(p.pmd["sigma2_mm2"]) for p in sel})
    fig = new_figure(15, 4.4)
    axes = fig.subplots(1, 3, sharex=True)
    excluded = folded_any = False
    for ax, panel in zip(axes, PANELS, strict=True):
        folded, hollow = _visibility_panel(ax, panel, sel, sigma2s, paper_image)
        folded_any |= folded
        excluded |= hollow
    axes[0].invert_xaxis()
    legend_outside(fig, axes[0], _visibility_legend(folded_any, excluded))
    fig.suptitle(
        f"{surface_name(surface)}, dmax = {dmax * 1000:g} µm: a PMD station against the "
        "camera's elevation, beside the paper's metric",
        fontsize=11,
    )
    fig.tight_layout()
    save_figure(fig, path, within=path.parent)


def _visibility_panel(
    ax,
    panel: tuple,
    sel: Sequence[Pair],
    sigma2s: Sequence[float],
    paper_image: tuple[int, int] | None,
) -> tuple[bool, bool]:
    """One of :data:`PANELS` on ``ax``: a series per σ², the axis scaled to the
    measurable cases; whether any case folds, and whether any not measurable was drawn."""
    side, key, law, title, unit = panel
    rows = [(p, r) for p in sel if (r := p.pmd if side == "pmd" else p.paper) is not None]
    ok_values = [_value(r, key) for _, r in rows if is_measurable(r)]
    limits = _limits(ok_values)
    folded_any = excluded = False
    for s2 in sigma2s:
        series = sorted(
            (pr for pr in rows if float(pr[0].pmd["sigma2_mm2"]) == s2),
            key=lambda pr: float(pr[0].pmd["theta_deg"]),
        )
        folded, hollow = _visibility_series(ax, series, s2, key, law, limits)
        folded_any |= folded
        excluded |= hollow
    if limits is not None:
        ax.set_ylim(*limits)
    ax.set_title(title, fontsize=10)
    ax.set_xlabel("θ (deg)")
    ax.set_ylabel(pixels_label(paper_image) if unit == "px" else (unit or "ratio"))
    ax.grid(alpha=0.3)
    return folded_any, excluded


def _visibility_series(
    ax,
    series: Sequence[tuple[Pair, Mapping]],
    s2: float,
    key: str,
    law: str | None,
    limits: tuple[float, float] | None,
) -> tuple[bool, bool]:
    """One σ²'s cases (``series``, in θ order) on a panel: the measurable ones joined
    (rings where the stripe map folds), the closed form ``law`` dashed, the others hollow;
    whether any measurable case folds, and whether any not measurable was drawn."""
    good = [pr for pr in series if is_measurable(pr[1])]
    theta = np.array([float(p.pmd["theta_deg"]) for p, _ in good])
    value = np.array([_value(r, key) for _, r in good])
    (handle,) = ax.plot(theta, value, marker="o", label=f"σ² = {s2:g} mm²")
    if law is not None:  # where the law holds (not at grazing views)
        ax.plot(
            [float(p.pmd["theta_deg"]) for p, _ in series],
            [_value(p.pmd, law) if p.law_holds else math.nan for p, _ in series],
            ls="--", lw=1, color=handle.get_color(),
        )  # fmt: skip
    folds = np.array([p.folds for p, _ in good], bool)
    if folds.any():
        ax.scatter(
            theta[folds], value[folds], s=130, facecolors="none",
            edgecolors=handle.get_color(),
        )  # fmt: skip
    bad = [pr for pr in series if not is_measurable(pr[1])]
    hollow = False
    if bad:
        hollow = _hollow(
            ax,
            [float(p.pmd["theta_deg"]) for p, _ in bad],
            [_value(r, key) for _, r in bad],
            limits,
        )
    return bool(folds.any()), hollow


def _visibility_legend(folded_any: bool, excluded: bool) -> list:
    """The visibility figure's legend entries beyond the σ² lines: the closed form, the
    rings of folded cases and the hollow markers, where drawn."""
    from matplotlib.lines import Line2D

    extra = [
        Line2D([], [], color="k", ls="--", lw=1,
               label="closed form 2 α (De + σ cos θ) · G (none where it is marked grazing)")
    ]  # fmt: skip
    if folded_any:
        extra.append(
            Line2D(
                [],
                [],
                color="k",
                marker="o",
                ls="none",
                markerfacecolor="none",
                markersize=11,
                label="stripe map folds (fold ratio > 1)",
            )  # fmt: skip
        )
    if excluded:
        extra.append(_hollow_handle())
    return extra


def depth_plot(pairs: Sequence[Pair], path: Path, surfaces, dmaxs) -> None:
    """The reconstructed depth of every case against θ: a panel per surface (columns)
    and depth (rows), one colour per σ², the true depth dashed."""
    from matplotlib.lines import Line2D

    fig = new_figure(4.6 * len(surfaces) + 2.0, 3.6 * len(dmaxs))
    axes = np.atleast_2d(fig.subplots(len(dmaxs), len(surfaces), squeeze=False))
    excluded = off_scale = False
    sigma2s = sorted({float(p.pmd["sigma2_mm2"]) for p in pairs})
    colours = dict(zip(sigma2s, [f"C{i}" for i in range(len(sigma2s))], strict=True))
    for i, dmax in enumerate(dmaxs):
        for j, surface in enumerate(surfaces):
            ax = axes[i, j]
            sel = [
                p.pmd
                for p in pairs
                if p.pmd["surface"] == surface and float(p.pmd["dmax_mm"]) == dmax
            ]
            truth = 1000.0 * dmax
            limits = (0.0, DEPTH_RANGE * truth)
            for s2 in sigma2s:
                series = sorted(
                    (r for r in sel if float(r["sigma2_mm2"]) == s2),
                    key=lambda r: float(r["theta_deg"]),
                )
                good = [r for r in series if is_measurable(r)]
                theta = np.array([float(r["theta_deg"]) for r in good])
                depth = np.array([_value(r, "pmd_depth_um") for r in good])
                shown = np.clip(depth, *limits)
                ax.plot(theta, shown, marker="o", color=colours[s2], label=f"σ² = {s2:g} mm²")
                off = np.isfinite(depth) & (depth != shown)
                if off.any():
                    off_scale = True
                    ax.scatter(theta[off], shown[off], marker="X", s=90, color=colours[s2])
                    for t, y, value in zip(theta[off], shown[off], depth[off], strict=True):
                        ax.annotate(
                            f"{value:.3g} µm", (t, y), textcoords="offset points",
                            xytext=(14, -12 if y > truth else 8), ha="center", fontsize=7.5,
                            color=colours[s2],
                        )  # fmt: skip
                bad = [r for r in series if not is_measurable(r)]
                if bad:
                    excluded |= _hollow(
                        ax,
                        [float(r["theta_deg"]) for r in bad],
                        [_value(r, "pmd_depth_um") for r in bad],
                        limits,
                    )
            ax.axhline(truth, color="k", ls="--", lw=1)
            ax.set_ylim(-0.12 * truth, (DEPTH_RANGE + 0.12) * truth)
            ax.invert_xaxis()
            ax.grid(alpha=0.3)
            ax.set_title(f"{surface_name(surface)}, dmax = {truth:g} µm", fontsize=10)
            ax.set_xlabel("θ (deg)")
            ax.set_ylabel("reconstructed depth (µm)")
    extra = [Line2D([], [], color="k", ls="--", lw=1, label="true depth dmax")]
    if off_scale:
        extra.append(
            Line2D(
                [],
                [],
                color="k",
                marker="X",
                ls="none",
                label=f"off the axis (0 to {DEPTH_RANGE:g} dmax): at its edge, value written",
            )  # fmt: skip
        )
    if excluded:
        extra.append(_hollow_handle())
    legend_outside(fig, axes[0, 0], extra)
    fig.suptitle(
        "The dent's depth as a PMD station reconstructs it (slopes integrated, a Gaussian "
        "fitted), against θ",
        fontsize=11,
    )
    fig.tight_layout()
    save_figure(fig, path, within=path.parent)


def law_plot(pairs: Sequence[Pair], path: Path) -> None:
    """The PMD shift against its closed form (left; triangles where the stripe map
    folds; every measurable case whose law holds) and the measured noise against its
    prediction (right; every case whose two noisy decodes agree on the fringe)."""
    from glshade.study.pmd_findings import fringe_noise

    fig = new_figure(12, 5)
    axes = fig.subplots(1, 2)
    colours = surface_colours(dict.fromkeys(p.pmd["surface"] for p in pairs))
    for surface, colour in colours.items():
        mine = [
            p for p in pairs if p.pmd["surface"] == surface and is_measurable(p.pmd) and p.law_holds
        ]
        for folds, marker in ((False, "o"), (True, "^")):
            pick = [p for p in mine if p.folds == folds]
            if pick:
                axes[0].scatter(
                    [_value(p.pmd, "pmd_shift_law_mm") for p in pick],
                    [_value(p.pmd, "pmd_shift_mm") for p in pick],
                    c=colour, marker=marker, s=22,
                    label=f"{surface_name(surface)}{', stripe map folds' if folds else ''}",
                )  # fmt: skip
        noisy = [p.pmd for p in pairs if p.pmd["surface"] == surface and not fringe_noise(p.pmd)]
        if noisy:
            axes[1].scatter(
                [_value(r, "pmd_noise_predicted_mm") for r in noisy],
                [_value(r, "pmd_noise_mm") for r in noisy],
                c=colour, s=22, label=surface_name(surface),
            )  # fmt: skip
    for ax, title, unit in (
        (axes[0], "largest decoded shift: 2 α_max (De + σ cos θ) · G", "mm on the screen"),
        (axes[1], "decoded noise: p₀/(2π) · sqrt(2/N) · σ_I / B", "mm on the screen"),
    ):
        ax.set_xscale("log")
        ax.set_yscale("log")
        _plain_log_ticks(ax)
        lo, hi = ax.get_xlim()
        ax.plot([lo, hi], [lo, hi], color="k", lw=1, label="simulation = closed form")
        ax.plot([lo, hi], [lo * 1.1, hi * 1.1], color="k", lw=0.6, ls=":", label="±10 %")
        ax.plot([lo, hi], [lo / 1.1, hi / 1.1], color="k", lw=0.6, ls=":")
        ax.set_xlabel(f"closed form ({unit})")
        ax.set_ylabel(f"simulation ({unit})")
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3, which="both")
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(
        handles, labels, fontsize=9, loc="center left", bbox_to_anchor=(1.0, 0.5), frameon=False
    )
    fig.suptitle("Phase measuring: the closed forms against the simulation", fontsize=11)
    fig.tight_layout()
    save_figure(fig, path, within=path.parent)


def _plain_log_ticks(ax) -> None:
    """Log axes labelled with plain numbers (0.2, 0.5, 1), not powers of ten, and no
    labels on the minor ticks (they collide)."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    for axis in (ax.xaxis, ax.yaxis):
        axis.set_major_locator(LogLocator(base=10.0, subs=(1.0, 2.0, 5.0)))
        axis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
        axis.set_minor_formatter(NullFormatter())


def write_pmd_figures(
    pmd_rows: Sequence[Mapping],
    paper_rows: Sequence[Mapping],
    out_dir: Path,
    plan,
    paper_image: tuple[int, int] | None = None,
) -> list[Path]:
    """Every figure of the PMD study; returns their paths."""
    out_dir = Path(out_dir)
    pairs = pair_rows(pmd_rows, paper_rows, plan)
    written: list[Path] = []
    if len(plan.thetas) >= 2:
        for surface in plan.surfaces:
            for dmax in plan.dmaxs:
                path = out_dir / visibility_name(surface, dmax)
                visibility_plot(pairs, surface, dmax, path, paper_image)
                written.append(path)
        depth_plot(pairs, out_dir / DEPTH_FIGURE, plan.surfaces, plan.dmaxs)
        written.append(out_dir / DEPTH_FIGURE)
    if pairs:
        law_plot(pairs, out_dir / LAW_FIGURE)
        written.append(out_dir / LAW_FIGURE)
    return written
