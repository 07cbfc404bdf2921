"""Figures of the study, after the paper's: image grids (Figs. 10, 11, 14, 15, 18, 19),
visibility-against-θ plots (Figs. 12, 13, 16, 17, 20, 21), the Fig. 9 contour overlay,
and the closed forms against the simulation.

Every figure is drawn from ``results.csv`` rows (the overlay from the images of its case),
names its case in its title, labels its axes with units and has a legend for every colour.
matplotlib's object API on the Agg canvas: no display, no pyplot state, safe off the main
thread. Every file is written atomically. Depths are shown in µm, as the titles say.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from glshade.files import read_png
from glshade.instruments.figures import new_figure as _figure
from glshade.instruments.figures import save_figure as _save
from glshade.study.notation import image_size
from glshade.study.plan import GRID_THETAS, StudyPlan, case_key, surface_label
from glshade.study.status import is_measurable, status_of
from glshade.study.store import CaseResult

SURFACE_NAMES = {"flat": "flat plate", "cylinder": "cylinder, R 70 mm", "sphere": "sphere, R 70 mm"}


def legend_outside(fig, axis, extra: list) -> None:
    """The figure's legend right of its plots, outside the data: ``axis``'s lines, then
    the ``extra`` handles (markers for folds, cases that cannot be read)."""
    handles, labels = axis.get_legend_handles_labels()
    fig.legend(
        handles + extra,
        labels + [h.get_label() for h in extra],
        fontsize=9,
        loc="center left",
        bbox_to_anchor=(1.0, 0.5),
        frameon=False,
    )


def surface_name(surface: str) -> str:
    """A surface as figure titles name it: the paper's by name, a free-form one by its
    scene file and what the surface is."""
    if surface in SURFACE_NAMES:
        return SURFACE_NAMES[surface]
    from glshade.study.plan import case_scene

    scene = case_scene(surface)
    return f"{surface_label(surface)}: {scene.active.surface.describe(scene)}"


SURFACE_COLOURS = {"flat": "tab:blue", "cylinder": "tab:orange", "sphere": "tab:green"}
#: Colours of the other surfaces of a study, in order.
MORE_COLOURS = ("tab:purple", "tab:brown", "tab:pink", "tab:olive", "tab:cyan", "tab:red")
#: How a row that is not measurable is drawn (hollow grey), and its legend entry.
NOT_MEASURABLE = {"facecolors": "none", "edgecolors": "0.55", "linewidths": 1.3}
NOT_MEASURABLE_LABEL = "not measurable"


def surface_colours(surfaces) -> dict[str, str]:
    """A colour for every surface of a study: the paper's own, then :data:`MORE_COLOURS`."""
    more = iter(MORE_COLOURS * 4)
    return {s: SURFACE_COLOURS.get(s) or next(more) for s in surfaces}


def pixels_label(image: tuple[int, int] | None) -> str:
    """The axis label of a length in pixels: of the run's image, when its size is known."""
    return f"pixels of the {image[0]}×{image[1]} image" if image else "pixels of the image"


def _not_measurable_handle():
    from matplotlib.lines import Line2D

    return Line2D(
        [], [], color="0.55", marker="o", ls="none", markerfacecolor="none",
        label=NOT_MEASURABLE_LABEL,
    )  # fmt: skip


def _um(dmax_mm: float) -> str:
    return f"{dmax_mm * 1000:g} µm"


# --------------------------------------------------------------------------- grids
def image_grid(
    rows: list[CaseResult], cases_dir: Path, surface: str, dmax: float, thetas, sigma2s, path: Path
) -> bool:
    """θ across, σ² down, each the defect image at its best phase. False when a case's
    thumbnail is missing (the grid is then not written). The thumbnails are tiled into one
    mosaic (one image to draw, not one axes per case)."""
    lookup = {
        (r.theta_deg, r.sigma2_mm2): r for r in rows if r.surface == surface and r.dmax_mm == dmax
    }
    tiles = []
    for s2 in sigma2s:
        line = []
        for t in thetas:
            png = Path(cases_dir) / f"{case_key(surface, t, s2, dmax)}.png"
            if not png.exists() or (t, s2) not in lookup:
                return False
            line.append(read_png(png))
        tiles.append(line)
    side = tiles[0][0].shape[0]
    gap = side // 12
    cell = side + gap
    mosaic = np.full((len(sigma2s) * cell - gap, len(thetas) * cell - gap), 255, np.uint8)
    for i, line in enumerate(tiles):
        for j, tile in enumerate(line):
            mosaic[i * cell : i * cell + side, j * cell : j * cell + side] = tile
    width_in = 2.3 * len(thetas) + 1.3
    fig = _figure(width_in, (width_in - 1.3) * mosaic.shape[0] / mosaic.shape[1] + 1.3)
    ax = fig.subplots()
    ax.imshow(mosaic, cmap="gray", vmin=0, vmax=255, interpolation="antialiased")
    ax.set_xticks(
        [j * cell + side / 2 for j in range(len(thetas))], [f"θ = {t:g}°" for t in thetas]
    )
    ax.set_yticks(
        [i * cell + side / 2 for i in range(len(sigma2s))], [f"σ² = {s2:g} mm²" for s2 in sigma2s]
    )
    ax.xaxis.tick_top()
    ax.tick_params(length=0, labelsize=10)
    for spine in ax.spines.values():
        spine.set_visible(False)
    for i, s2 in enumerate(sigma2s):
        for j, t in enumerate(thetas):
            r = lookup[(t, s2)]
            fold = ", folds" if r.folded else ""
            text = f"{r['visibility_px']:g} px (limit {r['visibility_continuous_px']:.1f}){fold}"
            if not is_measurable(r):
                text = f"not measurable: {status_of(r)}"
            ax.text(
                j * cell + side / 2,
                i * cell + side + gap * 0.1,
                text,
                ha="center",
                va="top",
                fontsize=7.5,
            )
    fig.suptitle(
        f"{surface_name(surface)}, dmax = {_um(dmax)}: image with the dent at its best phase",
        fontsize=11,
    )
    fig.text(
        0.5,
        0.01,
        "Below each image: the paper's visibility (px, whole pixels) and its continuous limit "
        "(px); "
        "'folds': the stripe map folds.",
        ha="center",
        fontsize=8,
    )
    _save(fig, path, within=path.parent)
    return True


# --------------------------------------------------------------------------- against θ
PLOT_PANELS = (
    ("visibility_px", "visibility_law_px", "paper's metric (whole px)"),
    ("visibility_continuous_px", "visibility_law_px", "continuous limit of the metric"),
    ("deflection_px", "deflection_law_px", "deflection of the rays"),
)


def visibility_plot(
    rows: list[CaseResult],
    surface: str,
    dmax: float,
    path: Path,
    image: tuple[int, int] | None = None,
) -> None:
    """The three numbers against θ, one colour per σ²: markers the simulation, dashed
    lines the closed forms (docs/physics.md); rings mark cases whose stripe map folds,
    hollow grey markers the cases that are not measurable (left out of the lines).
    ``image``: the run's image size, for the axis label."""
    from matplotlib.lines import Line2D

    sel = [r for r in rows if r.surface == surface and r.dmax_mm == dmax]
    sigma2s = sorted({r.sigma2_mm2 for r in sel})
    fig = _figure(15, 4.3)
    axes = fig.subplots(1, 3, sharex=True, sharey=True)
    excluded = False
    for ax, (key, law_key, title) in zip(axes, PLOT_PANELS, strict=False):
        for s2 in sigma2s:
            series = sorted((r for r in sel if r.sigma2_mm2 == s2), key=lambda r: r.theta_deg)
            line = [r for r in series if is_measurable(r)]
            bad = [r for r in series if not is_measurable(r)]
            theta = np.array([r.theta_deg for r in line])
            value = np.array([r[key] for r in line])
            (handle,) = ax.plot(theta, value, marker="o", label=f"σ² = {s2:g} mm²")
            ax.plot(
                [r.theta_deg for r in series],
                [r[law_key] for r in series],
                ls="--",
                lw=1,
                color=handle.get_color(),
            )
            folded = np.array([r.folded for r in line], bool)
            if folded.any():
                ax.scatter(
                    theta[folded],
                    value[folded],
                    s=130,
                    facecolors="none",
                    edgecolors=handle.get_color(),
                )
            if bad:
                excluded = True
                ax.scatter(
                    [r.theta_deg for r in bad], [r[key] for r in bad], s=40, **NOT_MEASURABLE
                )
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("θ (deg)")
        ax.invert_xaxis()
        ax.grid(alpha=0.3)
    axes[0].set_ylabel(pixels_label(image))
    extra = [
        Line2D([], [], color="k", ls="--", lw=1, label="closed form"),
        Line2D(
            [],
            [],
            color="k",
            marker="o",
            ls="none",
            markerfacecolor="none",
            markersize=11,
            label="stripe map folds",
        ),
    ]
    if excluded:
        extra.append(_not_measurable_handle())
    legend_outside(fig, axes[0], extra)
    fig.suptitle(
        f"{surface_name(surface)}, dmax = {_um(dmax)}: visibility against the camera's elevation",
        fontsize=11,
    )
    fig.tight_layout()
    _save(fig, path, within=path.parent)


def law_plot(rows: list[CaseResult], path: Path, image: tuple[int, int] | None = None) -> None:
    """Closed form against simulation for every case: the deflection (left) and the
    visible shift (right, the continuous limit against the fold-capped law); cases that
    are not measurable as hollow grey markers. ``image``: the run's image size."""
    fig = _figure(12, 5)
    colours = surface_colours(dict.fromkeys(r.surface for r in rows))
    unit = pixels_label(image)
    excluded = False
    axes = fig.subplots(1, 2)
    for ax, (sim, law, title) in zip(
        axes,
        (
            ("deflection_px", "deflection_law_px", "deflection"),
            (
                "visibility_continuous_px",
                "visibility_law_px",
                "visible contour shift (continuous limit)",
            ),
        ),
        strict=False,
    ):
        drawable = [
            r
            for r in rows
            if r[law] is not None and math.isfinite(r[law]) and r[law] > 0 and r[sim] > 0
        ]
        bad = [r for r in drawable if not is_measurable(r)]
        if bad:
            excluded = True
            ax.scatter([r[law] for r in bad], [r[sim] for r in bad], s=26, **NOT_MEASURABLE)
        for surface, colour in colours.items():
            for folded, marker in ((False, "o"), (True, "^")):
                pick = [
                    r
                    for r in drawable
                    if r.surface == surface and r.folded == folded and is_measurable(r)
                ]
                if pick:
                    ax.scatter(
                        [r[law] for r in pick],
                        [r[sim] for r in pick],
                        c=colour,
                        marker=marker,
                        s=22,
                        label=f"{surface_name(surface)}{', folds' if folded else ''}",
                    )
        ax.set_xscale("log")
        ax.set_yscale("log")
        lo, hi = ax.get_xlim()
        ax.plot([lo, hi], [lo, hi], color="k", lw=1, label="simulation = law")
        ax.plot([lo, hi], [lo * 1.1, hi * 1.1], color="k", lw=0.6, ls=":", label="±10 %")
        ax.plot([lo, hi], [lo / 1.1, hi / 1.1], color="k", lw=0.6, ls=":")
        ax.set_xlabel(f"closed form ({unit})")
        ax.set_ylabel(f"simulation ({unit})")
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3, which="both")
    handles, labels = axes[0].get_legend_handles_labels()
    if excluded:
        handles.append(_not_measurable_handle())
        labels.append(NOT_MEASURABLE_LABEL)
    fig.legend(
        handles, labels, fontsize=9, loc="center left", bbox_to_anchor=(1.0, 0.5), frameon=False
    )
    fig.suptitle(
        f"Closed forms against the simulation, all {len(rows)} cases (docs/physics.md)", fontsize=11
    )
    fig.tight_layout()
    _save(fig, path, within=path.parent)


# --------------------------------------------------------------------------- Fig. 9
def figure_names(surface: str, dmax: float) -> tuple[str, str]:
    """File names of the grid and the plot of one (surface, depth); depth in µm."""
    tag = f"{surface_label(surface)}_dmax{dmax * 1000:g}um"
    return f"grid_{tag}.png", f"visibility_{tag}.png"


LAW_FIGURE = "law_vs_simulation.png"


def surface_figures(
    rows: list[CaseResult], out_dir: Path, plan: StudyPlan, surface: str
) -> list[Path]:
    """The grids and plots of one surface (from its rows); returns the paths written."""
    out_dir = Path(out_dir)
    written = []
    grid_thetas = [t for t in GRID_THETAS if t in plan.thetas]
    mine = [r for r in rows if r.surface == surface]
    for dmax in plan.dmaxs:
        grid_name, plot_name = figure_names(surface, dmax)
        if grid_thetas and image_grid(
            mine, out_dir / "cases", surface, dmax, grid_thetas, plan.sigma2s, out_dir / grid_name
        ):
            written.append(out_dir / grid_name)
        if len(plan.thetas) >= 2:
            visibility_plot(mine, surface, dmax, out_dir / plot_name, image_size(plan))
            written.append(out_dir / plot_name)
    return written


def write_figures(
    rows: list[CaseResult], out_dir: Path, plan, drawn: dict[str, list[Path]] | None = None
) -> list[Path]:
    """Every grid and plot the plan's rows allow, and the closed forms against the
    simulation; ``drawn``: surfaces whose figures were drawn already (and their paths).
    Returns the paths of all of them."""
    out_dir = Path(out_dir)
    drawn = drawn or {}
    written = []
    for surface in plan.surfaces:
        written += (
            drawn[surface] if surface in drawn else surface_figures(rows, out_dir, plan, surface)
        )
    if rows:
        law_plot(rows, out_dir / LAW_FIGURE, image_size(plan))
        written.append(out_dir / LAW_FIGURE)
    return written
