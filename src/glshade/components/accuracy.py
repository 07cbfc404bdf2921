"""A component's accuracy knob: the setting that trades its error for its run time, and
how ``glshade accuracy`` measures it (``docs/accuracy.md``).

A component that has one returns an :class:`AccuracyKnob` from ``accuracy_knob()``; the
knob lives in the component's folder (its ``accuracy.py``). ``glshade.validation.accuracy``
hands every knob an :class:`AccuracyBench`: the renderer, the NumPy fp64 oracle, a timer
and the paper's scenes, so a knob needs nothing above the components. Each setting it
measures is a :class:`KnobPoint`; the Pareto front and the report's tables are here too.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, Protocol, TypeVar

import numpy as np
from numpy.typing import NDArray

T = TypeVar("T")


@dataclass(frozen=True)
class KnobPoint:
    """One setting of one knob: its worst error over the scenes (per currency: ``uv`` mm,
    ``image`` of the emitter peak, ``visibility`` px, ...) and its median time."""

    knob: str
    label: str
    seconds: float
    errors: dict[str, float]
    default: bool = False


class AccuracyBench(Protocol):
    """What ``glshade accuracy`` gives a knob to measure with."""

    size: int  # pixels across of the per-frame measurements
    repeats: int  # timed repeats per setting
    surfaces: tuple[str, ...]  # the paper's surfaces the run is restricted to
    directory: Path  # scratch space for the run (files the knob writes)

    def paper_scene(self, surface: str, theta: float, sigma2: float, dmax: float) -> Any:
        """The paper's scene (``glshade.scene.paper_scene``)."""
        ...

    def render(self, scene: Any, outputs: tuple[str, ...] = ("image",)) -> Any:
        """A frame of the GLSL renderer."""
        ...

    def reference(self, scene: Any, outputs: tuple[str, ...]) -> Any:
        """The NumPy fp64 oracle's frame."""
        ...

    def hits(self, scene: Any, rows: Any = None, cols: Any = None) -> tuple[np.ndarray, ...]:
        """The oracle's first hits of the pixels' chief rays (a window of the sensor):
        ``(directions, points, unit normals, hit)``, (N, 3) each and (N,)."""
        ...

    def timed(self, work: Callable[[], T], repeats: int) -> tuple[float, T]:
        """``(median seconds, last result)`` of ``work`` run ``repeats`` times."""
        ...

    def log(self, message: str) -> None: ...


class AccuracyKnob:
    """A component's knob: ``measure`` its settings, write its ``section`` of the report.
    ``figures``: ``(currency, title, unit, file name)`` of its own plots; ``joins_frames``:
    its points also join the per-frame image plot; ``defaults``: ``(currency, what)`` the
    report's "Defaults" list checks its default against."""

    name: ClassVar[str]
    figures: ClassVar[tuple[tuple[str, str, str, str], ...]] = ()
    joins_frames: ClassVar[bool] = False
    defaults: ClassVar[tuple[tuple[str, str], ...]] = ()

    def measure(self, bench: AccuracyBench) -> list[KnobPoint]:
        raise NotImplementedError

    def section(self, points: list[KnobPoint], bench: AccuracyBench) -> list[str]:
        raise NotImplementedError


def image_errors(
    image: NDArray[np.floating[Any]],
    ref_image: NDArray[np.floating[Any]],
    mask: NDArray[np.bool_],
) -> tuple[float, float]:
    """Largest and RMS difference of two radiance images over ``mask``."""
    diff = np.abs(image.astype(np.float64) - ref_image)[mask]
    return (float(diff.max()), float(np.sqrt(np.mean(diff**2)))) if diff.size else (0.0, 0.0)


#: Differences in time or error below this fraction are noise, not dominance.
NOISE = 0.10


def _dominates(q: KnobPoint, p: KnobPoint, currency: str) -> bool:
    qt, pt, qe, pe = q.seconds, p.seconds, q.errors[currency], p.errors[currency]
    no_worse = qt <= pt * (1 + NOISE) and qe <= pe * (1 + NOISE)
    clearly_better = qt < pt * (1 - NOISE) or qe < pe * (1 - NOISE)
    return q is not p and no_worse and clearly_better


def pareto(points: list[KnobPoint], currency: str) -> list[KnobPoint]:
    """The points no other point beats, by more than the timing noise, in time or error
    without losing in the other."""
    have = [p for p in points if currency in p.errors]
    return sorted(
        (p for p in have if not any(_dominates(q, p, currency) for q in have)),
        key=lambda p: p.seconds,
    )


def points_table(points: list[KnobPoint], currencies: list[tuple[str, str]]) -> list[str]:
    """The markdown table of a knob's points: time, the errors in each currency, and the
    fronts each is on."""
    head = (
        "| knob | setting | ms | "
        + " | ".join(name for _, name in currencies)
        + " | on the Pareto front |"
    )
    lines = [head, "|" + "---|" * (4 + len(currencies))]
    fronts = {c: {id(p) for p in pareto(points, c)} for c, _ in currencies}
    for p in points:
        cells = [f"{p.errors[c]:.2e}" if c in p.errors else "—" for c, _ in currencies]
        on = ", ".join(name for c, name in currencies if id(p) in fronts[c]) or "no"
        label = f"**{p.label}** (default)" if p.default else p.label
        lines.append(
            f"| {p.knob} | {label} | {p.seconds * 1e3:.1f} | " + " | ".join(cells) + f" | {on} |"
        )
    return lines
