"""Figures of one measurement, made where it is measured: the Fig. 9 contour overlay (the
two cut contour images at the best phase, the largest distance drawn), and the small
matplotlib helpers the study's figures share (headless: the Agg canvas)."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from glshade.files import atomic_write_bytes
from glshade.metrics.contours import overlay_rgb

#: The Fig. 9 colours (RGB 0-1) and what they mean.
OVERLAY_LEGEND = (
    ((0.0, 0.0, 1.0), "contour, defect-free image"),
    ((1.0, 0.0, 0.0), "contour, image with the dent"),
    ((1.0, 0.0, 1.0), "both (contours coincide)"),
    ((1.0, 150 / 255, 0.0), "island of a fold (not measured)"),
)


def new_figure(width_in: float, height_in: float):
    """A matplotlib figure (no pyplot, no display)."""
    from matplotlib.figure import Figure

    return Figure(figsize=(width_in, height_in))


def save_figure(fig, path: Path) -> None:
    """Write ``fig`` as a PNG, atomically."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110, bbox_inches="tight")
    atomic_write_bytes(Path(path), buffer.getvalue())


def write_overlay(baseline, v1, result, images, title: str, path: Path) -> None:
    """The Fig. 9 overlay of a measured case (its baseline, emitter map, result and, for
    rendered shading, its phase images) at its best phase."""
    normal, defect = baseline.stripes_at(v1, result.best_phase_mm, result.offset_px, images)
    overlay_figure(overlay_rgb(normal, defect), result, baseline.columns.start, title, path)


def overlay_figure(
    rgb: np.ndarray, result, column_start: int, title: str, path: Path, zoom_px: int = 48
) -> None:
    """The Fig. 9 overlay of one case at its best phase: the cut contour images merged
    (left), a magnified window around the largest distance with that distance drawn
    (right), a title naming the case and a legend for every colour.

    ``rgb``: :func:`glshade.metrics.contours.overlay_rgb` of the kept columns; ``result``: the
    case's :class:`glshade.metrics.visibility.Visibility`; ``column_start``: the first kept column.
    """
    from matplotlib.patches import Patch, Rectangle

    shift = result.shift
    fig = new_figure(12, 6.2)
    full, near = fig.subplots(1, 2, gridspec_kw={"width_ratios": (1.0, 1.0)})
    height, width = rgb.shape[:2]
    full.imshow(
        rgb,
        interpolation="antialiased",
        extent=(column_start - 0.5, column_start + width - 0.5, height - 0.5, -0.5),
    )
    full.set_title("kept columns (cut at both sides)", fontsize=9)
    full.set_xlabel("image column (px)")
    full.set_ylabel("image row (px)")
    if shift.column >= 0:
        rows = (shift.normal_row, shift.defect_row)
        centre_row = 0.5 * (rows[0] + rows[1])
        half = max(zoom_px, abs(rows[0] - rows[1]) * 0.75 + 8)
        x0, x1 = shift.column - half, shift.column + half
        y0, y1 = centre_row - half, centre_row + half
        full.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, edgecolor="yellow", lw=1))
        near.imshow(rgb, interpolation="nearest", extent=full.images[0].get_extent())
        near.set_xlim(x0, x1)
        near.set_ylim(y1, y0)
        near.annotate(
            "",
            xy=(shift.column, rows[1]),
            xytext=(shift.column, rows[0]),
            arrowprops={"arrowstyle": "<->", "color": "yellow", "lw": 1.5},
        )
        near.text(
            shift.column + 2,
            centre_row,
            f" {shift.distance_px:g} px\n ({shift.side} contour)",
            color="yellow",
            fontsize=10,
            va="center",
        )
        near.set_title("magnified: the largest distance between corresponding contours", fontsize=9)
    else:
        near.set_title("no corresponding contours to compare", fontsize=9)
    near.set_xlabel("image column (px)")
    handles = [Patch(color=c, label=text) for c, text in OVERLAY_LEGEND]
    handles.append(Patch(color="yellow", label="measured distance"))
    fig.legend(handles=handles, loc="lower center", ncol=5, fontsize=8.5)
    fig.suptitle(
        f"Fig. 9 overlay: {title}; phase {result.best_phase_mm:g} mm\n"
        f"visibility {result.visibility_px:g} px (limit {result.visibility_continuous_px:.2f} px, "
        f"deflection {result.deflection_px:.2f} px, {result.islands} islands)",
        fontsize=10.5,
    )
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    save_figure(fig, path)
