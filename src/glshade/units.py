"""Quantities as a user types them: a number with an optional unit.

A bare number is in the parameter's own unit (``docs/scene-format.md``: lengths in mm,
a few in µm, areas in mm², angles in degrees), so ``--dmax 5`` is still 5 mm. A value may
also carry its unit wherever a number is typed: on the command line (``--dmax 5um``,
``--sigma2 4mm2``, ``--theta 0.5rad``, ``--family defect.dmax=3um..5um``) and, as a
string, in a scene file, a sweep's grid or ``Scene.with_value`` (``dmax = "5 um"``;
:meth:`glshade.params.Param.check`).

The text is read by a scanner that looks at each character once (no regular expression,
so no backtracking), and only after its length is checked: at most
:data:`MAX_QUANTITY_CHARS` characters once the surrounding blanks are stripped. Units are
case-sensitive, as SI writes them: ``Mm`` would be a megametre, so it is refused with a
line that suggests ``mm`` rather than read as one.
"""

from __future__ import annotations

import math

from glshade.errors import SceneError, printable

#: The longest quantity read, in characters (blanks around it not counted): room for a
#: float's 17 significant digits, its sign, point and exponent, a unit and blanks, four
#: times over. A longer text is refused before it is scanned.
MAX_QUANTITY_CHARS = 64
#: Characters of a refused text shown in its error line.
EXCERPT_CHARS = 24

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
#: What a unit spelled in another case would mean, where it means something.
_OTHER_CASE = {
    "Mm": "megametres",
    "Nm": "newton-metres",
    "Cm": "coulomb-metres",
    "M": "the prefix mega",
    "Mrad": "megaradians",
}
_DIGITS = frozenset("0123456789")


class QuantityError(SceneError):
    """A quantity refused for its spelling (longer than :data:`MAX_QUANTITY_CHARS`, a
    unit in the wrong case). Its line says all; a caller that rephrases a malformed value
    in its own words passes this one on unchanged."""

    def __init__(self, field: str, allowed: str, got: str, why: str) -> None:
        super().__init__(field, allowed, got)
        self.args = (printable(f"{field}: {why}"),)


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


def excerpt(text: str) -> str:
    """The start of a long ``text``, quoted, for an error line."""
    return repr(text[:EXCERPT_CHARS]) + ("..." if len(text) > EXCERPT_CHARS else "")


def parse_quantity(text: str, unit: str, field: str) -> float:
    """``text`` as a number in ``unit``: ``"5um"`` with unit ``mm`` is 0.005. A
    :class:`SceneError` names ``field`` and says how to write the value (a
    :class:`QuantityError` for a text too long or a unit in the wrong case). The result
    is not range-checked (``nan`` and ``inf`` pass through to the parameter's check).
    Time and memory are linear in ``len(text)``."""
    text = text.strip()
    if len(text) > MAX_QUANTITY_CHARS:
        why = (
            f"a value of at most {MAX_QUANTITY_CHARS} characters (a number with an optional "
            f"unit), got {len(text)} characters: {excerpt(text)}"
        )
        raise QuantityError(field, f"at most {MAX_QUANTITY_CHARS} characters", text, why)
    try:
        return float(text)
    except ValueError:
        pass
    end = number_end(text)
    suffix = text[end:].lstrip()
    if end == 0 or not suffix or any(c.isspace() for c in suffix):
        raise SceneError(field, examples(unit), text)
    return float(text[:end]) * unit_factor(suffix, unit, field, text)


def number_end(text: str) -> int:
    """Where the decimal number that starts ``text`` ends (0: none there):
    ``[+-]digits[.digits][(e|E)[+-]digits]`` with ASCII digits, at least one in the
    mantissa; an ``e`` not followed by digits is left to the unit. One pass, no
    backtracking beyond the exponent's two characters."""
    at, size = 0, len(text)
    if at < size and text[at] in "+-":
        at += 1
    digits = 0
    while at < size and text[at] in _DIGITS:
        at, digits = at + 1, digits + 1
    if at < size and text[at] == ".":
        at += 1
        while at < size and text[at] in _DIGITS:
            at, digits = at + 1, digits + 1
    if digits == 0:
        return 0
    if at < size and text[at] in "eE":
        exponent = at + 1
        if exponent < size and text[exponent] in "+-":
            exponent += 1
        if exponent < size and text[exponent] in _DIGITS:
            at = exponent
            while at < size and text[at] in _DIGITS:
                at += 1
    return at


def unit_factor(suffix: str, unit: str, field: str, text: str) -> float:
    """The factor from ``suffix`` (a unit as typed) to ``unit``; a SceneError naming
    ``field`` for an unknown unit, a QuantityError for a known one in the wrong case."""
    factors = units_for(unit)
    if suffix in factors:
        return factors[suffix]
    if not factors:
        raise SceneError(field, f"{examples(unit)}, without a unit", text)
    meant = next((name for name in factors if name.lower() == suffix.lower()), None)
    if meant is not None:
        meaning = _OTHER_CASE.get(suffix)
        aside = f" ({suffix} would be {meaning})" if meaning else ""
        why = f"unit {suffix!r} in {text!r}: did you mean {meant}? units are case-sensitive{aside}"
        raise QuantityError(field, examples(unit), text, why)
    raise SceneError(field, f"{examples(unit)} (units: {', '.join(sorted(factors))})", text)
