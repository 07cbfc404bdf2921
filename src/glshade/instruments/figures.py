"""Figures of one measurement, made where it is measured: the Fig. 9 contour overlay (the
two cut contour images at the best phase, the largest distance drawn), and the small
matplotlib helpers the study's figures share (headless: the Agg canvas)."""

from __future__ import annotations

import io
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from glshade.files import atomic_write_bytes
from glshade.metrics.contours import overlay_rgb

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from glshade.metrics.contours import ContourShift
    from glshade.metrics.visibility import Baseline, Visibility

#: The contour masks :func:`_contour_masks` makes: defect-free, with the dent, islands.
_Masks = tuple[np.ndarray, np.ndarray, np.ndarray]
#: An image's extent on its axes (left, right, bottom, top).
_Extent = tuple[float, float, float, float]

#: The Fig. 9 overlay's colours (RGB 0-1, distinct in print and for colour-blind readers)
#: and what they mean; drawn on white.
DEFECT_FREE = (0.0, 0.35, 0.75)
WITH_DENT = (0.85, 0.2, 0.0)
BOTH = (0.62, 0.62, 0.62)
ISLAND = (0.0, 0.62, 0.45)
SHIFT = (0.85, 0.0, 0.6)
OVERLAY_LEGEND = (
    (DEFECT_FREE, "contour, defect-free image"),
    (WITH_DENT, "contour, image with the dent"),
    (BOTH, "both (contours coincide)"),
    (ISLAND, "island of a fold (not measured)"),
)


def new_figure(width_in: float, height_in: float) -> Figure:
    """A matplotlib figure (no pyplot, no display)."""
    from matplotlib.figure import Figure

    return Figure(figsize=(width_in, height_in))


def save_figure(fig: Figure, path: Path, dpi: int = 110, within: Path | None = None) -> None:
    """Write ``fig`` as a PNG, atomically; ``within``: the output directory it belongs to
    (:func:`glshade.files.atomic_write_bytes`)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi, bbox_inches="tight")
    atomic_write_bytes(Path(path), buffer.getvalue(), within=within)


def write_overlay(
    baseline: Baseline,
    v1: np.ndarray,
    result: Visibility,
    images: Callable[[float], np.ndarray] | None,
    title: str,
    path: Path,
) -> None:
    """The Fig. 9 overlay of a measured case (its baseline, emitter map, result and, for
    rendered shading, its phase images) at its best phase."""
    normal, defect = baseline.stripes_at(v1, result.best_phase_mm, result.offset_px, images)
    if result.status != "ok":  # the picture says what its number says
        title = f"{title} [{result.status}: not measurable]"
    overlay_figure(overlay_rgb(normal, defect), result, baseline.columns.start, title, path)


def _contour_masks(rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The defect-free contours, the dent's measured contours and its islands, from
    :func:`glshade.metrics.contours.overlay_rgb`'s colours."""
    island = (rgb[..., 0] == 255) & (rgb[..., 1] == 150) & (rgb[..., 2] == 0)
    normal = rgb[..., 2] == 255
    defect = (rgb[..., 0] == 255) & ~island
    return normal, defect, island


def _paint(masks: tuple[np.ndarray, np.ndarray, np.ndarray], thickness: int) -> np.ndarray:
    """The contours on white (float RGB), each ``thickness`` pixels wide: the defect-free
    ones, the dent's over them, black where both coincide, the islands on top."""
    import cv2

    if thickness > 1:
        kernel = np.ones((thickness, thickness), np.uint8)
        masks = tuple(cv2.dilate(m.astype(np.uint8), kernel) > 0 for m in masks)  # type: ignore[assignment]
    normal, defect, island = masks
    image = np.ones(normal.shape + (3,))
    image[normal] = DEFECT_FREE
    image[defect] = WITH_DENT
    image[normal & defect] = BOTH
    image[island] = ISLAND
    return image


@dataclass(frozen=True)
class _Window:
    """The magnified window around the largest distance: its column, the two contour rows
    it joins and its bounds (image columns ``x0``-``x1``, rows ``y0``-``y1``)."""

    column: float
    rows: tuple[float, float]
    x0: float
    x1: float
    y0: float
    y1: float

    @classmethod
    def around(cls, shift: ContourShift, zoom_px: int) -> _Window:
        """The square window centred on ``shift``'s two rows, at least ``zoom_px`` pixels
        from its centre to each side and wide enough to show both rows."""
        rows = (shift.normal_row, shift.defect_row)
        centre_row = 0.5 * (rows[0] + rows[1])
        half = max(zoom_px, abs(rows[0] - rows[1]) * 0.75 + 8)
        return cls(
            column=shift.column,
            rows=rows,
            x0=shift.column - half,
            x1=shift.column + half,
            y0=centre_row - half,
            y1=centre_row + half,
        )


def _label_axes(ax: Axes) -> None:
    """Name an image axis's columns and rows in pixels."""
    ax.set_xlabel("image column (px)", fontsize=10)
    ax.set_ylabel("image row (px)", fontsize=10)


def _draw_kept_columns(full: Axes, masks: _Masks, extent: _Extent, height: int) -> None:
    """The left panel: every kept column, its contours thickened to stay visible in print,
    titled and with its axes labelled."""
    full.imshow(
        _paint(masks, max(1, round(height / 300))), interpolation="antialiased", extent=extent
    )
    full.set_title("kept columns (cut at both sides)", fontsize=10)
    _label_axes(full)


def _mark_window(full: Axes, window: _Window, width: int, height: int) -> None:
    """The magnified window outlined on the left panel, with a ``magnified`` label."""
    from matplotlib.patches import Rectangle

    x0, x1, y0, y1 = window.x0, window.x1, window.y0, window.y1
    full.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, edgecolor=SHIFT, lw=2))
    full.annotate(
        "magnified",
        xy=(x1, y0),
        xytext=(x1 + 0.08 * width, y0 - 0.06 * height),
        color=SHIFT,
        fontsize=9,
        bbox={"boxstyle": "round", "fc": "white", "ec": SHIFT, "alpha": 0.9},
        arrowprops={"arrowstyle": "-", "color": SHIFT, "lw": 1},
    )


def _draw_magnified(
    near: Axes, masks: _Masks, extent: _Extent, window: _Window, shift: ContourShift
) -> None:
    """The right panel: the window at one pixel per contour, the two contour points
    circled and joined by a double arrow, titled with the shift."""
    near.imshow(_paint(masks, 1), interpolation="nearest", extent=extent)
    near.set_xlim(window.x0, window.x1)
    near.set_ylim(window.y1, window.y0)
    rows = window.rows
    for row in rows:
        near.plot([window.column], [row], "o", ms=6, mfc="none", mec=SHIFT, mew=1.5)
    near.annotate(
        "",
        xy=(window.column, rows[1]),
        xytext=(window.column, rows[0]),
        arrowprops={"arrowstyle": "<|-|>", "color": SHIFT, "lw": 2, "shrinkA": 0, "shrinkB": 0},
    )
    near.set_title(
        "magnified: the largest distance between corresponding contours\n"
        f"shift {shift.distance_px:g} px ({shift.side} contour, column {shift.column:g})",
        fontsize=10,
        color=SHIFT,
    )


def _overlay_title(result: Visibility, title: str, width: int, height: int) -> str:
    """The overlay's title: the case, its best phase, its visibility and its image."""
    return (
        f"Fig. 9 overlay: {title}; phase {result.best_phase_mm:g} mm\n"
        f"visibility {result.visibility_px:g} px (limit {result.visibility_continuous_px:.2f} px, "
        f"deflection {result.deflection_px:.2f} px, {result.islands} islands); "
        f"image {width} kept columns × {height} rows"
    )


def overlay_figure(
    rgb: np.ndarray,
    result: Visibility,
    column_start: int,
    title: str,
    path: Path,
    zoom_px: int = 40,
    within: Path | None = None,
) -> None:
    """The Fig. 9 overlay of one case at its best phase: the cut contour images merged
    (left, contours thickened to stay visible at print size), a magnified window around
    the largest distance with that distance marked and annotated (right), a title naming
    the case and a legend for every colour.

    ``rgb``: :func:`glshade.metrics.contours.overlay_rgb` of the kept columns; ``result``: the
    case's :class:`glshade.metrics.visibility.Visibility`; ``column_start``: the first kept column.
    """
    from matplotlib.lines import Line2D

    shift = result.shift
    masks = _contour_masks(rgb)
    height, width = rgb.shape[:2]
    extent = (column_start - 0.5, column_start + width - 0.5, height - 0.5, -0.5)
    fig = new_figure(11, 6.4)
    full, near = fig.subplots(1, 2, gridspec_kw={"width_ratios": (0.8, 1.2)})
    _draw_kept_columns(full, masks, extent, height)
    handles = [Line2D([], [], color=colour, lw=3, label=text) for colour, text in OVERLAY_LEGEND]
    if shift.column >= 0:
        window = _Window.around(shift, zoom_px)
        _mark_window(full, window, width, height)
        _draw_magnified(near, masks, extent, window, shift)
        handles.append(
            Line2D([], [], color=SHIFT, lw=2, marker="o", mfc="none", label="measured shift")
        )
    else:
        near.set_title("no corresponding contours to compare", fontsize=10)
    _label_axes(near)
    fig.legend(
        handles=handles, loc="upper center", bbox_to_anchor=(0.5, 0.02), ncol=3, fontsize=10,
        frameon=False,
    )  # fmt: skip
    fig.suptitle(_overlay_title(result, title, width, height), fontsize=11)
    fig.tight_layout()
    save_figure(fig, path, dpi=150, within=within)
