"""Figures of the study, after the paper's: image grids (Figs. 10, 11, 14, 15, 18, 19)
and visibility-against-θ line plots (Figs. 12, 13, 16, 17, 20, 21), as PNG.

matplotlib runs on its Agg backend (no display); every file is written atomically.
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from .files import atomic_write_bytes, read_png

SURFACE_NAMES = {"flat": "flat surface", "cylinder": "cylinder, R 70 mm", "sphere": "sphere, R 70 mm"}


def _figure():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _save(fig, path: Path) -> None:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110, bbox_inches="tight")
    atomic_write_bytes(Path(path), buffer.getvalue())


def image_grid(rows: list[dict], cases_dir: Path, surface: str, dmax: float, thetas, sigma2s, path: Path) -> bool:
    """θ across, σ² down, each the defect image at its best phase. False when a case's
    thumbnail is missing (the grid is then not written)."""
    from .study import case_key

    plt = _figure()
    lookup = {(r["theta_deg"], r["sigma2_mm2"]): r for r in rows if r["surface"] == surface and r["dmax_mm"] == dmax}
    images = {}
    for s2 in sigma2s:
        for t in thetas:
            png = Path(cases_dir) / f"{case_key(surface, t, s2, dmax)}.png"
            if not png.exists() or (t, s2) not in lookup:
                return False
            images[(t, s2)] = read_png(png)
    fig, axes = plt.subplots(len(sigma2s), len(thetas), figsize=(2.2 * len(thetas), 2.2 * len(sigma2s)), squeeze=False)
    for i, s2 in enumerate(sigma2s):
        for j, t in enumerate(thetas):
            ax = axes[i][j]
            ax.imshow(images[(t, s2)], cmap="gray", vmin=0, vmax=255, interpolation="nearest")
            ax.set_xticks([])
            ax.set_yticks([])
            r = lookup[(t, s2)]
            ax.set_title(f"{r['visibility_px']:g} px @ {r['best_phase_mm']:g} mm", fontsize=8)
            if i == 0:
                ax.text(0.5, 1.25, f"θ = {t:g}°", transform=ax.transAxes, ha="center", fontsize=10)
            if j == 0:
                ax.set_ylabel(f"σ² = {s2:g} mm²", fontsize=10)
    fig.suptitle(f"{SURFACE_NAMES[surface]}, dmax = {dmax * 1000:g} µm (defect image at the best phase)", fontsize=11)
    fig.tight_layout()
    _save(fig, path)
    plt.close(fig)
    return True


def visibility_plot(rows: list[dict], surface: str, dmax: float, path: Path) -> None:
    """Visibility against θ, one line per σ²: the paper's pixel metric and the
    continuous metric side by side; folded cases are ringed."""
    plt = _figure()
    sel = [r for r in rows if r["surface"] == surface and r["dmax_mm"] == dmax]
    sigma2s = sorted({r["sigma2_mm2"] for r in sel})
    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharex=True)
    for ax, key, title in (
        (axes[0], "visibility_px", "paper metric (contour shift, px)"),
        (axes[1], "visibility_continuous_px", "continuous metric (px)"),
    ):
        for s2 in sigma2s:
            line = sorted((r for r in sel if r["sigma2_mm2"] == s2), key=lambda r: r["theta_deg"])
            theta = np.array([r["theta_deg"] for r in line])
            value = np.array([r[key] for r in line])
            (handle,) = ax.plot(theta, value, marker="o", label=f"σ² = {s2:g} mm²")
            folded = np.array([r["folded"] for r in line], bool)
            if folded.any():
                ax.scatter(theta[folded], value[folded], s=120, facecolors="none", edgecolors=handle.get_color())
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("θ (deg)")
        ax.invert_xaxis()
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("visibility (px)")
    axes[0].legend(fontsize=8)
    fig.suptitle(f"{SURFACE_NAMES[surface]}, dmax = {dmax * 1000:g} µm (rings: stripe map folds)", fontsize=11)
    fig.tight_layout()
    _save(fig, path)
    plt.close(fig)


def figure_names(surface: str, dmax: float) -> tuple[str, str]:
    """File names of the grid and the plot of one (surface, depth)."""
    tag = f"{surface}_dmax{dmax * 1000:g}um"
    return f"grid_{tag}.png", f"visibility_{tag}.png"


def write_figures(rows: list[dict], out_dir: Path, plan) -> list[Path]:
    """Every grid and plot the plan's rows allow; returns the paths written."""
    from .study import GRID_THETAS

    out_dir = Path(out_dir)
    written = []
    grid_thetas = [t for t in GRID_THETAS if t in plan.thetas]
    for surface in plan.surfaces:
        for dmax in plan.dmaxs:
            grid_name, plot_name = figure_names(surface, dmax)
            if grid_thetas and image_grid(rows, out_dir / "cases", surface, dmax, grid_thetas, plan.sigma2s, out_dir / grid_name):
                written.append(out_dir / grid_name)
            if len(plan.thetas) >= 2:
                visibility_plot(rows, surface, dmax, out_dir / plot_name)
                written.append(out_dir / plot_name)
    return written
