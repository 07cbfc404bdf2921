"""A shot against its baseline: which pixels and which numbers moved, by how much.

The numbers compared are the record's measured columns whose unit has a tolerance: the
paper's columns in px (``visibility_px`` and the others), a phase-measuring station's in mm
and µm; each instrument's ``status`` must be the same. Every other column is kept in the
sidecar and shown beside them, not compared.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from glshade.snapshot.baseline import Baseline
from glshade.snapshot.station import Shot
from glshade.snapshot.tolerance import ACROSS_RENDERERS, ACROSS_RENDERERS_FP64, Tolerances


@dataclass(frozen=True)
class ImageDifference:
    """``largest``: the largest per-pixel difference (fraction of the emitter's peak) at
    ``worst`` (row, column), where the baseline had ``expected`` and the shot ``actual``;
    ``beyond``: pixels differing by more than the tolerance; ``shape``: the baseline's and
    the shot's (height, width), compared only where they agree."""

    largest: float
    worst: tuple[int, int]
    expected: float
    actual: float
    beyond: int
    shapes: tuple[tuple[int, int], tuple[int, int]]

    @property
    def same_size(self) -> bool:
        return self.shapes[0] == self.shapes[1]

    def moved(self, tolerances: Tolerances) -> bool:
        return not self.same_size or self.beyond > tolerances.image_pixels

    def describe(self, tolerances: Tolerances) -> str:
        if not self.same_size:
            (h0, w0), (h1, w1) = self.shapes
            return f"image is {w1}x{h1} pixels, its baseline {w0}x{h0}"
        row, col = self.worst
        return (
            f"image: {self.beyond} pixels differ by more than {tolerances.image:g} of the "
            f"emitter's peak ({tolerances.image_pixels} allowed); the worst, row {row} column "
            f"{col}: {self.expected:.4f} -> {self.actual:.4f} ({self.largest:.2g})"
        )


def image_difference(expected: np.ndarray, actual: np.ndarray, tolerance: float) -> ImageDifference:
    """How ``actual`` differs from ``expected`` (float images, the emitter's peak at 1)."""
    shapes = (expected.shape[:2], actual.shape[:2])
    if shapes[0] != shapes[1]:
        return ImageDifference(math.inf, (0, 0), math.nan, math.nan, -1, shapes)
    delta = np.abs(np.nan_to_num(actual, nan=0.0) - np.nan_to_num(expected, nan=0.0))
    index = np.unravel_index(int(np.argmax(delta)), delta.shape) if delta.size else (0, 0)
    row, col = int(index[0]), int(index[1])
    return ImageDifference(
        largest=float(delta[row, col]) if delta.size else 0.0,
        worst=(row, col),
        expected=float(expected[row, col]) if delta.size else math.nan,
        actual=float(actual[row, col]) if delta.size else math.nan,
        beyond=int(np.count_nonzero(delta > tolerance)),
        shapes=shapes,
    )


@dataclass(frozen=True)
class NumberChange:
    """One measured number, then and now. ``tolerance``: in the number's ``unit``; None
    for a word (``status``) that must stay the same."""

    instrument: str
    name: str
    unit: str
    expected: Any
    actual: Any
    tolerance: float | None
    #: The status that makes the number unreadable now or in the baseline ("" if none).
    unreadable: str = ""

    @property
    def moved(self) -> bool:
        a, b = self.expected, self.actual
        if self.tolerance is None or a is None or b is None:
            return a != b
        if not (isinstance(a, (int, float)) and isinstance(b, (int, float))):
            return a != b
        # a hair over the tolerance: a difference of exactly it (one rounding step of a
        # record's column) is within it
        return abs(float(b) - float(a)) > self.tolerance * (1 + 1e-9)

    def describe(self) -> str:
        unit = f" {self.unit}" if self.unit else ""
        if self.tolerance is None:
            return f"{self.name} {self.expected} -> {self.actual}"
        delta = ""
        if isinstance(self.expected, (int, float)) and isinstance(self.actual, (int, float)):
            delta = f", by {float(self.actual) - float(self.expected):+.4g}"
        trust = f", not readable: status {self.unreadable}" if self.unreadable else ""
        return (
            f"{self.name} {_shown(self.expected)} -> {_shown(self.actual)}{unit}{delta} "
            f"(tolerance {self.tolerance:g}{unit}{trust})"
        )


def _shown(value: Any) -> str:
    return "none" if value is None else f"{value:.6g}" if isinstance(value, float) else str(value)


def unreadable_by(instrument: str, column: str, *statuses: Any) -> str:
    """The first of ``statuses`` (now's, the baseline's) that makes ``column`` of
    ``instrument``'s record unreadable, as the tables mark it; "" where none does."""
    from glshade.instruments.registry import instrument as named

    chosen = named(instrument)
    for status in statuses:
        if isinstance(status, str) and chosen.concerns(status, column):
            return status
    return ""


def number_changes(
    expected: dict[str, dict[str, Any]], actual: dict[str, dict[str, Any]], tolerances: Tolerances
) -> list[NumberChange]:
    """Every compared number of every instrument either side measured."""
    from glshade.instruments.registry import instruments

    changes = []
    for instrument, chosen in instruments().by_name.items():
        if instrument not in expected and instrument not in actual:
            continue
        before, now = expected.get(instrument, {}), actual.get(instrument, {})
        for column in chosen.record_type.columns():
            if column.role != "measured":
                continue
            if column.name == "status":
                tolerance = None
            elif column.unit in chosen.compared_units:
                tolerance = getattr(tolerances, chosen.compared_units[column.unit])
            else:
                continue
            changes.append(
                NumberChange(
                    instrument, column.name, column.unit,
                    before.get(column.name), now.get(column.name), tolerance,
                    unreadable_by(instrument, column.name, now.get("status"), before.get("status")),
                )
            )  # fmt: skip
    return changes


def renderer_floor(
    baseline: str, actual: str, precision: str, level_step: float = 0.0
) -> tuple[Tolerances | None, str]:
    """The least tolerance a comparison between two renderers uses, and why (None, "" on
    one renderer). ``level_step``: a quantised screen's step between radiance levels,
    which a pixel may flip by where the renderers round a ray differently."""
    if baseline == actual:
        return None, ""
    floor = ACROSS_RENDERERS if precision == "fp32" else ACROSS_RENDERERS_FP64
    floor = dataclasses.replace(floor, image=floor.image + level_step)
    return floor, f"baseline made on {baseline}, compared on {actual}: tolerances at least " + (
        f"the measured renderer-to-renderer {floor.describe()}"
    )


def png_slack(image: np.ndarray) -> float:
    """Half a step of the 16-bit PNG a baseline image was stored in (its scale / 65535):
    what storing it may have moved a pixel by."""
    from glshade.snapshot.baseline import image_scale

    return 0.5 * image_scale(image) / 65535.0


@dataclass(frozen=True)
class Comparison:
    """A shot against its baseline with the tolerances used (``across``: why they were
    widened to the renderer-to-renderer floor, empty on one renderer)."""

    name: str
    image: ImageDifference
    numbers: tuple[NumberChange, ...]
    tolerances: Tolerances
    across: str

    @property
    def moved_numbers(self) -> list[NumberChange]:
        return [change for change in self.numbers if change.moved]

    @property
    def passed(self) -> bool:
        return not self.image.moved(self.tolerances) and not self.moved_numbers

    def message(self) -> str:
        """What moved, in one paragraph: the image's worst pixel, every number that moved."""
        parts = []
        if self.image.moved(self.tolerances):
            parts.append(self.image.describe(self.tolerances))
        for change in self.moved_numbers:
            parts.append(f"{change.instrument} {change.describe()}")
        text = f"snapshot {self.name!r} moved: " + "; ".join(parts)
        return text + (f" [{self.across}]" if self.across else "")


def compare(
    name: str, baseline: Baseline, shot: Shot, tolerances: Tolerances, identity: str
) -> Comparison:
    """``shot`` (made on renderer ``identity``) against ``baseline`` within ``tolerances``,
    widened to the renderer-to-renderer floor where the renderers differ."""
    floor, across = renderer_floor(baseline.renderer, identity, baseline.precision, shot.level_step)
    used = tolerances.at_least(floor) if floor is not None else tolerances
    return Comparison(
        name,
        image_difference(baseline.image, shot.image, used.image + png_slack(baseline.image)),
        tuple(number_changes(baseline.numbers, shot.numbers, used)),
        used,
        across,
    )


def scene_changes(baseline: dict[str, Any], now: dict[str, Any], limit: int = 4) -> str:
    """How the scene differs from the baseline's, at most ``limit`` keys
    (``camera.theta_deg 30 -> 35``), or "" where it is the same."""
    before, after = _flat(baseline), _flat(now)
    keys = [k for k in dict.fromkeys([*before, *after]) if before.get(k) != after.get(k)]
    shown = [f"{k} {before.get(k, 'unset')} -> {after.get(k, 'unset')}" for k in keys[:limit]]
    more = f" and {len(keys) - limit} more" if len(keys) > limit else ""
    return ", ".join(shown) + more


def _flat(tables: dict[str, Any]) -> dict[str, Any]:
    return {
        f"{table}.{key}": value
        for table, values in tables.items()
        if isinstance(values, dict)
        for key, value in values.items()
    }
