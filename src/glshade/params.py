"""One parameter schema: every scene parameter declared once, by the component that owns it.

A :class:`Param` carries its dotted path as it is spelled in a scene file
(``camera.theta_deg``), its unit, default, allowed range and role:

- ``feature``: its value picks shader code (changing it may compile another program);
- ``uniform``: its value reaches the shader as a uniform (changing it never recompiles).

A component declares its parameters as the fields of a frozen dataclass, its *table*,
each field made by :func:`param` (``theta_deg: float = param("camera.theta_deg", "deg",
45.0, ...)``): the field is the value a scene holds, its metadata the declaration. Scene
validation (:class:`Table`), TOML reading and writing, the CLI's ``--set PATH=VALUE`` and
short flags, the viewer's controls and ``docs/scene-format.md`` are all generated from
these declarations (:mod:`glshade.components.registry` collects them).
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields
from typing import Any, ClassVar

import numpy as np

from glshade.errors import SceneError
from glshade.units import QuantityError, examples, parse_quantity

#: How a value is typed: a real number, an integer, one of some names, a pair of numbers,
#: a fixed-length list of numbers (``size`` of them; 0: any non-empty list), a list of distinct
#: names (each one of ``choices``), a text (a formula), a table of named numbers.
VALUE_TYPES = (
    "real", "integer", "choice", "names", "pair", "vector", "text", "table", "path", "boolean"
)  # fmt: skip
#: The longest text value accepted.
MAX_TEXT = 2000
ROLES = ("feature", "uniform")


@dataclass(frozen=True)
class Control:
    """How the viewer shows a parameter: a slider over ``[lo, hi]`` (logarithmic when
    ``log``), its label ``name`` and ``fmt``. A slider's range is narrower than what
    validation allows: it is the range worth dragging through."""

    name: str
    lo: float
    hi: float
    log: bool = False
    fmt: str = "%.3f"
    signed: bool = False  # the slider sets |value|, the sign is kept (a concave radius)


@dataclass(frozen=True)
class Param:
    """One scene parameter.

    ``path``: ``table.key``; ``unit``: as the docs print it (``""`` when unitless);
    ``default``: the paper's value (``None``: unset, a documented fallback applies);
    ``value_type``: real | integer | choice | pair; ``lo``/``hi``: bounds (``None``: none),
    open unless ``closed``; ``nonzero``: 0 is refused; ``choices``: the allowed names
    (for a component selector the registry supplies them); ``role``: feature | uniform;
    ``flag``: the short CLI flag (``--theta``); ``control``: the viewer's slider;
    ``allowed_text``: what the error message says it accepts, where the range alone
    does not say it (a signed radius); ``stored``: False for a shorthand that sets other
    parameters (``defect.sigma2``) and is not a field of its table; ``plausible_max``: a
    magnitude beyond which the value is accepted but warned about (``plausible_why``
    says why), the usual sign of a value typed in the wrong unit; ``quiet``: a scene file
    lists it only where it differs from its default (a pose key a rig scene never sets).
    """

    path: str
    unit: str
    default: Any
    doc: str
    value_type: str = "real"
    lo: float | None = None
    hi: float | None = None
    closed: bool = False
    nonzero: bool = False
    choices: tuple[str, ...] = ()
    role: str = "uniform"
    flag: str | None = None
    control: Control | None = None
    allowed_text: str | None = None
    stored: bool = True
    plausible_max: float | None = None
    plausible_why: str = ""
    size: int = 0
    keywords: tuple[str, ...] = ()
    quiet: bool = False

    def __post_init__(self) -> None:
        if (
            self.value_type not in VALUE_TYPES
            or self.role not in ROLES
            or self.path.count(".") != 1
        ):
            raise ValueError(
                f"malformed parameter declaration {self.path!r} ({self.value_type}, {self.role})"
            )

    @property
    def table(self) -> str:
        return self.path.partition(".")[0]

    @property
    def key(self) -> str:
        return self.path.partition(".")[2]

    # ------------------------------------------------------------- validation
    def allowed(self, choices: tuple[str, ...] | None = None) -> str:
        """What the parameter accepts, in words: the text of its error message."""
        words = "".join(f' or "{word}"' for word in self.keywords)
        return self._allowed_values(choices) + words

    def _allowed_values(self, choices: tuple[str, ...] | None) -> str:
        unit = f" {self.unit}" if self.unit else ""
        if self.allowed_text is not None:
            return self.allowed_text
        if self.value_type == "choice":
            return "one of " + ", ".join(choices if choices is not None else self.choices)
        if self.value_type == "boolean":
            return "true or false"
        if self.value_type == "pair":
            return f"two numbers [u, v] > 0 ({self.unit})"
        if self.value_type == "vector":
            if not self.size:
                return "a non-empty list of finite numbers"
            return f"a list of {self.size} finite numbers"
        if self.value_type == "names":
            return "a non-empty list of distinct names, each one of " + ", ".join(self.choices)
        if self.value_type == "text":
            return f"a text of at most {MAX_TEXT} characters"
        if self.value_type == "path":
            return "a file path (relative to the scene file)"
        if self.value_type == "table":
            return "a table of name = number"
        if self.value_type == "integer":
            return f"an integer in [{self.lo:g}, {self.hi:g}]"
        if self.nonzero:
            return f"non-zero{unit}"
        if self.lo is not None and self.hi is not None:
            left, right = ("[", "]") if self.closed else ("(", ")")
            shown = " degrees" if self.unit == "deg" else unit
            return f"in {left}{self.lo:g}, {self.hi:g}{right}{shown}"
        if self.lo is not None:
            return f"a finite number {'>=' if self.closed else '>'} {self.lo:g}"
        return "a finite number"

    def check(self, value: Any, choices: tuple[str, ...] | None = None) -> Any:
        """The value normalised (float, int, str, tuple), or a :class:`SceneError` naming
        the field and what it allows."""
        if value is None and self.default is None:
            return None
        if isinstance(value, str) and value.strip() in self.keywords:
            return value.strip()
        value = self._quantities(value)
        if self.value_type == "choice":
            allowed = choices if choices is not None else self.choices
            if value not in allowed:
                raise SceneError(self.path, self.allowed(allowed), value)
            return value
        if self.value_type == "integer":
            return self._integer(value)
        if self.value_type == "boolean":
            if not isinstance(value, (bool, np.bool_)):
                raise SceneError(self.path, self.allowed(), value)
            return bool(value)
        if self.value_type == "names":
            if isinstance(value, str):
                value = [value]
            if (
                not isinstance(value, (list, tuple))
                or not value
                or any(name not in self.choices for name in value)
                or len(set(value)) != len(value)
            ):
                raise SceneError(
                    self.path, self.allowed(), list(value) if isinstance(value, tuple) else value
                )
            return tuple(value)
        if self.value_type == "path":
            if isinstance(value, os.PathLike):
                value = os.fspath(value)
            if (
                not isinstance(value, str)
                or not value.strip()
                or "\0" in value
                or len(value) > 4096
            ):
                raise SceneError(
                    self.path,
                    self.allowed(),
                    value if isinstance(value, str) else type(value).__name__,
                )
            return value
        if self.value_type == "text":
            if not isinstance(value, str) or not value.strip() or len(value) > MAX_TEXT:
                raise SceneError(
                    self.path,
                    self.allowed(),
                    value if isinstance(value, str) else type(value).__name__,
                )
            return value
        if self.value_type == "table":
            return self._table(value)
        if self.value_type == "pair":
            if not isinstance(value, (list, tuple, np.ndarray)) or len(value) != 2:
                raise SceneError(self.path, self.allowed(), value)
            return (self._real(value[0]), self._real(value[1]))
        if self.value_type == "vector":
            if not isinstance(value, (list, tuple, np.ndarray)) or (
                len(value) != self.size if self.size else not len(value)
            ):
                raise SceneError(
                    self.path, self.allowed(), list(value) if isinstance(value, tuple) else value
                )
            return tuple(self._finite(number) for number in value)
        return self._real(value)

    def _quantities(self, value: Any) -> Any:
        """Text with a unit (``"5 um"`` in a scene file, ``Scene.with_value``, a sweep
        grid) -> the number in the parameter's unit, for the numeric types (each element
        of a pair or vector); anything else unchanged (and checked as it is)."""
        if self.value_type in ("real", "integer") and isinstance(value, str):
            number = self._quantity(value)
            return int(number) if self.value_type == "integer" and number.is_integer() else number
        if self.value_type in ("pair", "vector") and isinstance(value, (list, tuple)):
            return type(value)(self._quantity(v) if isinstance(v, str) else v for v in value)
        return value

    def _quantity(self, text: str, entry: str | None = None) -> float:
        """``text`` as a number in the parameter's unit (or with its own); a malformed
        value or an unknown unit is a SceneError naming the parameter (``entry``: the
        named entry of a table), what it allows and how to write it."""
        field = self.path if entry is None else f"{self.path}.{entry}"
        try:
            return parse_quantity(text, self.unit, field)
        except QuantityError:
            raise
        except SceneError:
            allowed = "a finite number" if entry is not None else self.allowed()
            how = examples(self.unit) + ("" if self.unit else ", without a unit")
            raise SceneError(field, f"{allowed} ({how})", text) from None

    def _finite(self, value: Any) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
            raise SceneError(
                self.path, self.allowed() if self.keywords else "a finite number", value
            )
        number = as_float(value)
        if number is None or not math.isfinite(number):
            raise SceneError(self.path, "a finite number", value)
        return number

    def _real(self, value: Any) -> float:
        value = self._finite(value)
        if self.nonzero and value == 0.0:
            raise SceneError(self.path, self.allowed(), value)
        below = self.lo is not None and (value < self.lo if self.closed else value <= self.lo)
        above = self.hi is not None and (value > self.hi if self.closed else value >= self.hi)
        if below or above:
            raise SceneError(self.path, self.allowed(), value)
        return value

    def _table(self, value: Any) -> tuple[tuple[str, float], ...]:
        """``{name: number}`` (or its items) -> a tuple of ``(name, float)`` pairs, in
        order (hashable, so a scene stays a value)."""
        items = value.items() if isinstance(value, dict) else value
        try:
            pairs = [(name, number) for name, number in items]
        except (TypeError, ValueError):
            raise SceneError(self.path, self.allowed(), value) from None
        out = []
        for name, number in pairs:
            if not isinstance(name, str):
                raise SceneError(self.path, self.allowed(), value)
            if isinstance(number, str):  # "0.5", or with a unit where the table has one
                number = self._quantity(number, name)
            finite = (
                None
                if isinstance(number, bool) or not isinstance(number, (int, float))
                else as_float(number)
            )
            if finite is None or not math.isfinite(finite):
                raise SceneError(f"{self.path}.{name}", "a finite number", number)
            out.append((name, finite))
        return tuple(out)

    def _integer(self, value: Any) -> int:
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            if isinstance(value, float) and value.is_integer():
                value = int(value)
            else:
                raise SceneError(self.path, self.allowed(), value)
        value = int(value)
        if not self.lo <= value <= self.hi:
            raise SceneError(self.path, self.allowed(), value)
        return value

    def implausible(self, value: Any) -> str | None:
        """A warning line when an accepted ``value`` is beyond what is plausible (a dent
        50 mm deep: most likely µm meant), else None."""
        if (
            self.plausible_max is None
            or not isinstance(value, (int, float))
            or abs(value) <= self.plausible_max
        ):
            return None
        unit = f" {self.unit}" if self.unit else ""
        example = {"mm": ", write 5um for micrometres", "mm²": ", write 4um2 for µm²"}.get(
            self.unit, ""
        )
        note = f"; values are in {self.unit}{example}" if self.unit else ""
        return (
            f"{self.path} = {value:g}{unit} is beyond {self.plausible_max:g}{unit} "
            f"({self.plausible_why}){note}"
        )

    # ------------------------------------------------------------- text
    def parse(self, text: str) -> Any:
        """A value from command-line text (``--set camera.theta_deg=15``, ``--dmax 5um``),
        unchecked: a bare number is in the parameter's unit, or it carries its own
        (:mod:`glshade.units`)."""
        text = text.strip()
        if self.value_type in ("choice", "text", "path") or text in self.keywords:
            return text
        if self.value_type == "boolean":
            words = {"true": True, "false": False, "yes": True, "no": False, "1": True, "0": False}
            return words.get(text.lower(), text)
        if self.value_type == "names":
            return tuple(
                p
                for p in text.strip("[]()")
                .replace(",", " ")
                .replace('"', " ")
                .replace("'", " ")
                .split()
            )
        if self.value_type == "table":
            return tuple(
                (name.strip(), self.parse_entry(name.strip(), number))
                for name, _, number in (
                    part.partition("=") for part in text.split(",") if part.strip()
                )
            )
        if self.value_type in ("pair", "vector"):
            parts = [p for p in text.strip("[]()").replace(",", " ").split() if p]
            return tuple(parse_quantity(p, self.unit, self.path) for p in parts)
        number = parse_quantity(text, self.unit, self.path)
        if self.value_type == "integer" and number.is_integer():
            return int(number)
        return number

    def parse_entry(self, name: str, text: str) -> float:
        """One named entry of a table parameter from command-line text
        (``--set surface.parameters.a=0.2``), unchecked: a number in the table's unit,
        or with its own where the table has one."""
        return parse_quantity(text, self.unit, f"{self.path}.{name}")

    def default_text(self) -> str:
        """The default as a scene file would spell it."""
        if self.default is None:
            return "unset"
        if self.value_type == "boolean":
            return "true" if self.default else "false"
        if self.value_type in ("choice", "text", "path") or self.default in self.keywords:
            return f'"{self.default}"'
        if self.value_type == "table":
            return (
                "{ " + ", ".join(f"{k} = {v:g}" for k, v in self.default) + " }"
                if self.default
                else "{}"
            )
        if self.value_type in ("pair", "vector"):
            return "[" + ", ".join(f"{number:g}" for number in self.default) + "]"
        if self.value_type == "names":
            return "[" + ", ".join(f'"{name}"' for name in self.default) + "]"
        return f"{self.default:g}"


def as_float(value: Any) -> float | None:
    """``value`` (a number) as a float; None for an integer beyond a float's range
    (``10**400`` in a TOML file)."""
    try:
        return float(value)
    except OverflowError:
        return None


#: A check over several values of one table (after each was checked on its own).
TableCheck = Callable[[dict[str, Any]], None]


#: The key of a table field's metadata that holds its :class:`Param`.
PARAM_KEY = "glshade.param"


def param(path: str, unit: str, default: Any, doc: str, **options: Any) -> Any:
    """A table field declared with its :class:`Param`: its default is the field's, the
    declaration is in the field's metadata (``path``'s key must be the field's name)."""
    declared = Param(path, unit, default, doc, **options)
    return field(default=declared.default, metadata={PARAM_KEY: declared})


def turn_param(path: str, doc: str) -> Any:
    """A pose's turn about one of its own axes (degrees, in [-180, 180], default 0; quiet:
    scene files list it only where it is not 0)."""
    return param(path, "deg", 0.0, doc, lo=-180.0, hi=180.0, closed=True, quiet=True)


def point_param(path: str, default: tuple[float, float, float], doc: str, unit: str = "mm") -> Any:
    """A pose's point or direction: three numbers (quiet: listed only where it is not the
    default)."""
    return param(path, unit, default, doc, value_type="vector", size=3, quiet=True)


def declared_params(table_class: type) -> tuple[Param, ...]:
    """The declarations of a table dataclass's fields, in field order (shared fields, from
    a common base class, are the same :class:`Param` objects)."""
    found = []
    for item in fields(table_class):
        declared = item.metadata.get(PARAM_KEY)
        if declared is None:
            continue
        if declared.key != item.name:
            raise ValueError(f"{table_class.__name__}.{item.name} declares {declared.path}")
        found.append(declared)
    return tuple(found)


class Table:
    """Base of the scene's tables: frozen dataclasses whose fields are declared with
    :func:`param`. Construction checks each value against its declaration (the names a
    selector accepts are :attr:`selector_choices`), then the checks over several values
    that the table and its bases list in ``table_checks``; a bad value raises a
    :class:`SceneError` naming the field as a scene file spells it."""

    #: The table's name in scene files (``camera``); every field's path starts with it.
    table: ClassVar[str]
    #: Checks over several values of the table (after each value was checked alone).
    table_checks: ClassVar[tuple[TableCheck, ...]] = ()
    #: Field name -> the names a selector field accepts (the registered components).
    selector_choices: ClassVar[Mapping[str, tuple[str, ...]]] = {}

    def __post_init__(self) -> None:
        values = {}
        for item in fields(self):  # type: ignore[arg-type]
            declared = item.metadata.get(PARAM_KEY)
            if declared is None:
                continue
            value = declared.check(getattr(self, item.name), self.selector_choices.get(item.name))
            object.__setattr__(self, item.name, value)
            values[item.name] = value
        for check in self.checks():
            check(values)

    @classmethod
    def checks(cls) -> tuple[TableCheck, ...]:
        """The table's checks and its bases', each once."""
        found: dict[TableCheck, None] = {}
        for klass in reversed(cls.__mro__):
            found.update(dict.fromkeys(klass.__dict__.get("table_checks", ())))
        return tuple(found)

    @classmethod
    def declaration(cls, name: str) -> Param:
        """The declaration of field ``name``."""
        for item in fields(cls):  # type: ignore[arg-type]
            if item.name == name and PARAM_KEY in item.metadata:
                return item.metadata[PARAM_KEY]
        raise KeyError(f"{cls.__name__} has no declared field {name!r}")

    def effective(self, name: str) -> Any:
        """The value field ``name`` acts with: its own, or (where it is unset) what its
        documented fallback gives; a table with such fallbacks overrides this."""
        return getattr(self, name)

    def clamp(self, name: str, value: Any) -> Any:
        """``value`` for field ``name`` kept inside what the table accepts together with
        its other values (a slider's drag never makes a table invalid); a table with such
        joint constraints overrides this."""
        return value

    def values(self) -> dict[str, Any]:
        """Field name -> value, in declaration order."""
        return {item.name: getattr(self, item.name) for item in fields(self)}  # type: ignore[arg-type]
