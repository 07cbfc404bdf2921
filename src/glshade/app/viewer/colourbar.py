"""The colour bar of the colour-mapped views (the displacement, the PMD maps): its scale,
where it goes, its ticks, and its drawing (imgui's foreground draw list, over the
window). The scale, the ticks and the layout are plain functions, tested without a
display; only :func:`draw_colour_bar` needs imgui."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import numpy as np

#: The colour map of the displacement view and of its bar.
COLOUR_MAP = "viridis"
UNIT = "px"
#: The colour of a pixel with no value (NaN: no valid decode, nothing seen).
NO_VALUE_RGB = (110, 110, 110)
#: The bar's strip: caption line, ramp, tick marks and their numbers (pixels).
BAR_HEIGHT = 56
_MARGIN = 8
_RAMP_HEIGHT = 12
_TEXT_HEIGHT = 13  # imgui's default font


@dataclass(frozen=True)
class ColourScale:
    """A colour-mapped view's scale: values ``bottom`` to ``top`` in ``unit`` on the
    matplotlib colour map ``cmap`` (clipped at the ends), and the bar's ``caption``."""

    bottom: float
    top: float
    unit: str
    caption: str
    cmap: str = COLOUR_MAP


@cache
def colour_lut(cmap: str = COLOUR_MAP) -> np.ndarray:
    """The 256 colours (uint8 RGB) of a colour map, its low end (0 px) to its high end
    (the scale top)."""
    from matplotlib import colormaps

    return (colormaps[cmap](np.linspace(0, 1, 256))[:, :3] * 255).astype(np.uint8)


def colour_index(values: np.ndarray, top: float, bottom: float = 0.0) -> np.ndarray:
    """The LUT index of each value on a scale from ``bottom`` to ``top`` (clipped to the
    ends)."""
    span = top - bottom if top > bottom else 1.0
    scaled = (np.asarray(values, dtype=np.float64) - bottom) / span * 255
    return np.clip(scaled.astype(int), 0, 255)


def colour_mapped(values: np.ndarray, scale: ColourScale) -> np.ndarray:
    """``values`` (H, W) as an opaque RGBA image on ``scale``; NaN in
    :data:`NO_VALUE_RGB`."""
    finite = np.isfinite(values)
    index = colour_index(np.where(finite, values, scale.bottom), scale.top, scale.bottom)
    rgba = np.empty((*values.shape, 4), np.uint8)
    rgba[..., :3] = np.where(finite[..., None], colour_lut(scale.cmap)[index], NO_VALUE_RGB)
    rgba[..., 3] = 255
    return rgba


def _nice_step(top: float, most: int) -> float:
    """The smallest of 1, 2, 2.5, 5 × 10^k that cuts [0, top] into at most ``most`` steps."""
    raw = top / most
    power = 10.0 ** math.floor(math.log10(raw))
    for mantissa in (1.0, 2.0, 2.5, 5.0, 10.0):
        if mantissa * power >= raw * (1 - 1e-9):
            return mantissa * power
    return 10.0 * power  # pragma: no cover - the loop always returns


def _label(value: float, step: float) -> str:
    """``value`` with as many decimals as the step needs (0.25 -> 2, 2.5 -> 1, 5 -> 0)."""
    decimals = max(0, -math.floor(math.log10(step)))
    if not math.isclose(round(step, decimals), step, rel_tol=1e-9):
        decimals += 1
    return f"{value:.{decimals}f}"


@dataclass(frozen=True)
class Tick:
    """A tick of the bar: its value (in the scale's unit), its place along the bar (0 at
    the scale's bottom, 1 at its top) and its label."""

    value: float
    at: float
    label: str


def colour_bar_ticks(top: float, most: int = 5, bottom: float = 0.0) -> list[Tick]:
    """The bar's ticks for a scale from ``bottom`` (0 px) to ``top``: the round steps
    between them (at most ``most`` steps; 0 among them where the scale spans it), each
    at its place along the bar; only the bottom for an empty scale."""
    span = top - bottom
    if not (math.isfinite(span) and span > 0):
        return [Tick(bottom, 0.0, _label(bottom, 1.0))]
    step = _nice_step(span, most)
    first = math.ceil(bottom / step - 1e-9)
    last = math.floor(top / step + 1e-9)
    ticks = []
    for i in range(first, last + 1):
        value = i * step + 0.0  # no "-0"
        at = min(max((value - bottom) / span, 0.0), 1.0)
        ticks.append(Tick(value, at, _label(value, step)))
    return ticks


@dataclass(frozen=True)
class BarLayout:
    """Where the bar goes, in window pixels (top-left origin): the ramp's rectangle, and
    the strip behind it (caption, ramp, numbers)."""

    left: float
    top: float
    width: float
    height: float
    strip_top: float
    strip_bottom: float
    overlaid: bool  # drawn over the image's bottom edge (no room beneath it)


def colour_bar_layout(image_w: int, image_h: int, window_h: int) -> BarLayout:
    """Beneath the image where the window leaves room for it, else over the image's
    bottom edge (on a dark backdrop)."""
    overlaid = window_h - image_h < BAR_HEIGHT
    strip_top = image_h - BAR_HEIGHT if overlaid else image_h
    width = max(64, image_w - 2 * _MARGIN - 24)  # room for the unit on the right
    ramp_top = strip_top + 4 + _TEXT_HEIGHT + 4
    return BarLayout(
        left=_MARGIN,
        top=ramp_top,
        width=width,
        height=_RAMP_HEIGHT,
        strip_top=strip_top,
        strip_bottom=strip_top + BAR_HEIGHT,
        overlaid=overlaid,
    )


def caption(top: float) -> str:
    if top <= 0:
        return "displacement: measuring..."
    return f"displacement, {UNIT} (scale 0 to {top:.2f} {UNIT})"


def displacement_scale(top: float) -> ColourScale:
    """The displacement view's scale: 0 to the largest displacement (px)."""
    return ColourScale(0.0, top, UNIT, caption(top))


def draw_colour_bar(layout: BarLayout, image_w: int, scale: ColourScale) -> None:
    """Draw the bar of ``scale`` with imgui, over whatever the window shows there."""
    from imgui_bundle import imgui

    draw = imgui.get_foreground_draw_list()

    def colour(rgb, alpha: float = 1.0) -> int:
        return imgui.get_color_u32(imgui.ImVec4(rgb[0] / 255, rgb[1] / 255, rgb[2] / 255, alpha))

    white = colour((235, 235, 235))
    if layout.overlaid:
        draw.add_rect_filled(
            imgui.ImVec2(0, layout.strip_top),
            imgui.ImVec2(image_w, layout.strip_bottom),
            colour((20, 20, 20), 0.8),
        )
    # the caption stays over the image (clipped where the image is narrow)
    draw.push_clip_rect(
        imgui.ImVec2(0, layout.strip_top), imgui.ImVec2(image_w, layout.strip_bottom), True
    )
    draw.add_text(imgui.ImVec2(layout.left, layout.strip_top + 4), white, scale.caption)
    draw.pop_clip_rect()
    unit_w = imgui.calc_text_size(scale.unit).x
    width = min(layout.width, image_w - layout.left - unit_w - 8)  # room for the unit
    lut = colour_lut(scale.cmap)
    segments = 64
    for i in range(segments):
        a, b = i / segments, (i + 1) / segments
        left, right = lut[int(a * 255)], lut[int(b * 255)]
        draw.add_rect_filled_multi_color(
            imgui.ImVec2(layout.left + a * width, layout.top),
            imgui.ImVec2(layout.left + b * width, layout.top + layout.height),
            colour(left),
            colour(right),
            colour(right),
            colour(left),
        )
    bottom = layout.top + layout.height
    for tick in colour_bar_ticks(scale.top, bottom=scale.bottom):
        x = layout.left + tick.at * width
        draw.add_line(imgui.ImVec2(x, bottom), imgui.ImVec2(x, bottom + 4), white)
        text_w = imgui.calc_text_size(tick.label).x
        x_text = min(max(x - text_w / 2, 0.0), layout.left + width - text_w / 2)
        draw.add_text(imgui.ImVec2(x_text, bottom + 5), white, tick.label)
    draw.add_text(imgui.ImVec2(layout.left + width + 6, layout.top - 1), white, scale.unit)
