"""How the studies' reports write numbers, θ lists and stored text: plain functions, the
filters of the reports' templates (:mod:`glshade.study.templating` registers them, under
the names of :data:`FILTERS`). Nothing here knows a report; the analysis modules use
:func:`um` for the scopes they name.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Collection, Iterable

from glshade.study.escape import markdown_text
from glshade.study.plan import surface_label
from glshade.study.shapes import curvature_text


def um(dmax_mm: float) -> str:
    """A depth as the reports write it: in µm (``5 µm``)."""
    return f"{dmax_mm * 1000:g} µm"


def fmt(value: object, spec: str = "g") -> str:
    """``value`` in the format ``spec`` (Python's format mini-language: ``+.0%``)."""
    return format(value, spec)


def pattern(value: object, template: str) -> str:
    """``value`` through a ``str.format`` pattern (``{:.1f}``): a
    :class:`~glshade.study.findings_numbers.Scale`'s own."""
    return template.format(value)


def listed(values: Iterable[object], spec: str = "g", sep: str = ", ") -> str:
    """Numbers in a list: ``85, 45, 5``."""
    return sep.join(format(v, spec) for v in values)


def finite(values: Iterable[float | None]) -> list[float]:
    """The values that are numbers and finite."""
    return [float(v) for v in values if v is not None and math.isfinite(float(v))]


def is_finite(value: float | None) -> bool:
    """The template test ``is finite``: a number, and finite."""
    return value is not None and math.isfinite(float(value))


def num(value: float | None, spec: str = ".3g") -> str:
    """A number, or ``—`` where there is none (None or not finite)."""
    return "—" if value is None or not math.isfinite(float(value)) else format(value, spec)


def span(values: Iterable[float | None], spec: str) -> str:
    """The range of the finite values (``-3% to +5%``, one number when both ends read
    alike, ``—`` for none)."""
    kept = finite(values)
    if not kept:
        return "—"
    low, high = format(min(kept), spec), format(max(kept), spec)
    return low if low == high else f"{low} to {high}"


def median(values: Iterable[float | None], spec: str) -> str:
    """The median of the finite values, ``—`` for none."""
    kept = finite(values)
    return format(statistics.median(kept), spec) if kept else "—"


def change_range(changes: Collection[float]) -> str:
    """Relative changes as one range in whole per cent (``-3% to +5%``)."""
    low, high = min(changes), max(changes)
    return f"{low:+.0%}" if round(low, 2) == round(high, 2) else f"{low:+.0%} to {high:+.0%}"


def theta_ranges(chosen: Collection[float], plan_thetas: Iterable[float]) -> str:
    """Some of the study's θ as runs of neighbours in the plan: ``85–45°, 5°``."""
    order = sorted(plan_thetas, reverse=True)
    runs: list[list[float]] = []
    for i, t in enumerate(order):
        if t not in chosen:
            continue
        if runs and order.index(runs[-1][-1]) == i - 1:
            runs[-1].append(t)
        else:
            runs.append([t])
    if not runs:
        return "none"
    return ", ".join(f"{r[0]:g}–{r[-1]:g}°" if len(r) > 1 else f"{r[0]:g}°" for r in runs)


def paragraph(text: str) -> str:
    """A block of template lines as one line of Markdown (each line's ends stripped,
    joined by one space), ending in a line break: lets a template wrap a paragraph that the
    report keeps on one line."""
    return " ".join(line.strip() for line in text.strip("\n").split("\n")) + "\n"


#: The templates' filters: ``{{ d | um }}``, ``{{ x | fmt("+.0%") }}``, ``{{ reason | md }}``.
FILTERS = {
    "um": um,
    "fmt": fmt,
    "pattern": pattern,
    "listed": listed,
    "num": num,
    "finite": finite,
    "span": span,
    "median": median,
    "change_range": change_range,
    "theta_ranges": theta_ranges,
    "curvature": curvature_text,
    "label": surface_label,
    "md": markdown_text,
    "paragraph": paragraph,
}

#: The templates' tests: ``{% if value is finite %}``.
TESTS = {"finite": is_finite}
