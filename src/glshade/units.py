"""Quantities as a user types them: a number with an optional unit.

A bare number is in the parameter's own unit (``docs/scene-format.md``: lengths in mm,
a few in µm, areas in mm², angles in degrees), so ``--dmax 5`` is still 5 mm. A value may
also carry its unit wherever a number is typed: on the command line (``--dmax 5um``,
``--sigma2 4mm2``, ``--theta 0.5rad``, ``--family defect.dmax=3um..5um``) and, as a
string, in a scene file, a sweep's grid or ``Scene.with_value`` (``dmax = "5 um"``;
:meth:`glshade.params.Param.check`).
"""

from __future__ import annotations

import math
import re

from glshade.errors import SceneError

#: Length units, in mm.
LENGTHS_MM: dict[str, float] = {
    "nm": 1e-6,
    "um": 1e-3,
    "µm": 1e-3,
    "μm": 1e-3,
    "mm": 1.0,
    "cm": 10.0,
    "m": 1e3,
}
#: Angle units, in degrees.
ANGLES_DEG: dict[str, float] = {
    "deg": 1.0,
    "°": 1.0,
    "rad": 180.0 / math.pi,
    "mrad": 0.18 / math.pi,
}
_AREA_SUFFIXES = ("²", "^2", "2")
_QUANTITY = re.compile(r"^\s*([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)\s*([^\s\d.+-][^\s]*)?\s*$")


def units_for(unit: str) -> dict[str, float]:
    """The suffixes a value of ``unit`` (a parameter's unit: mm, µm, mm², deg, px or "")
    may carry, with their factor to ``unit``."""
    if unit == "mm":
        return dict(LENGTHS_MM)
    if unit in ("µm", "um"):
        return {name: factor * 1e3 for name, factor in LENGTHS_MM.items()}
    if unit == "mm²":
        return {
            name + suffix: factor**2
            for name, factor in LENGTHS_MM.items()
            for suffix in _AREA_SUFFIXES
        }
    if unit == "deg":
        return dict(ANGLES_DEG)
    if unit == "px":
        return {"px": 1.0}
    return {}


def examples(unit: str) -> str:
    """How a value of ``unit`` may be written, for error messages."""
    return {
        "mm": "a number in mm, or with a unit: 5um, 0.005mm, 2cm",
        "µm": "a number in µm, or with a unit: 0.55um, 550nm",
        "mm²": "a number in mm², or with a unit: 4mm2, 4e6um2",
        "deg": "a number in degrees, or with a unit: 15deg, 0.26rad",
    }.get(unit, f"a number{f' in {unit}' if unit else ''}")


def parse_quantity(text: str, unit: str, field: str) -> float:
    """``text`` as a number in ``unit``: ``"5um"`` with unit ``mm`` is 0.005. A
    :class:`SceneError` names ``field`` and says how to write the value. The result is
    not range-checked (``nan`` and ``inf`` pass through to the parameter's check)."""
    text = text.strip()
    try:
        return float(text)
    except ValueError:
        pass
    match = _QUANTITY.match(text)
    if match is None:
        raise SceneError(field, examples(unit), text)
    number, suffix = float(match.group(1)), match.group(2)
    factors = units_for(unit)
    factor = factors.get(suffix) if suffix is not None else 1.0
    if factor is None:
        factor = factors.get(suffix.lower())
    if factor is None:
        if not factors:
            raise SceneError(field, f"{examples(unit)}, without a unit", text)
        raise SceneError(field, f"{examples(unit)} (units: {', '.join(sorted(factors))})", text)
    return number * factor
