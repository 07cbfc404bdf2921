"""A budget file (docs/budget.md): what the station's calibration is uncertain of, and how
many draws the budget takes.

.. code-block:: toml

    draws = 16          # per input, and for the total (optional; default 32)
    seed = 1            # the draws' seed (optional; default 1)

    [uncertainty]       # dotted parameter path = standard deviation
    "camera.position[0]" = 0.5      # mm: the parameter's own unit
    "camera.yaw_deg" = "0.05deg"    # a value with a unit
    "camera.focal" = "0.5%"         # a percentage of the true value
    emitter.distance = 1.0          # a bare dotted key is the same path

Every path is checked against the schema (:func:`glshade.components.registry.registry`)
and the scene: a parameter that is a real number, or a vector's component (``[i]``), or
a named number of a table (``surface.parameters.a``), set in the scene; every standard
deviation is checked to be a finite number ``>= 0`` whose draws stay within the
parameter's range (:data:`RANGE_SIGMAS` standard deviations either side of the true
value are tried on the scene). A problem is one :class:`~glshade.errors.SceneError` line
naming the file, the key and what is allowed, before anything is measured or written.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from glshade.components.registry import registry
from glshade.errors import SceneError
from glshade.scene import Scene

#: The table of a budget file that maps parameter paths to standard deviations.
UNCERTAINTY_TABLE = "uncertainty"
#: Draws per input (and for the total) unless the file or ``--draws`` says otherwise.
DEFAULT_DRAWS = 32
#: The draws' seed unless the file or ``--seed`` says otherwise.
DEFAULT_SEED = 1
#: The fewest and the most draws per input.
DRAWS_RANGE = (2, 100_000)
#: The largest seed (NumPy's SeedSequence takes any non-negative integer; 2**63 - 1 keeps
#: it a TOML integer).
MAX_SEED = 2**63 - 1
#: The believed values ``true ± RANGE_SIGMAS σ`` must be values the scene accepts.
RANGE_SIGMAS = 4.0
#: The keys a budget file may hold at its top.
TOP_KEYS = ("draws", "seed", UNCERTAINTY_TABLE)
#: What a standard deviation may be, in words.
SIGMA_WORDS = (
    "a standard deviation: a finite number >= 0 in the parameter's unit{unit}, a value "
    'with a unit ("50um"), or a percentage of the true value ("0.5%")'
)


@dataclass(frozen=True)
class Input:
    """One uncertain input: its dotted ``path``, its standard deviation ``sigma`` in the
    parameter's ``unit`` (``""`` when it has none), the scene's ``true`` value, and the
    standard deviation as the file gave it (``given``: ``"0.5%"``, ``"0.5"``)."""

    path: str
    sigma: float
    unit: str
    true: float
    given: str

    @property
    def sigma_text(self) -> str:
        """The standard deviation as a table shows it: ``0.5 mm``, ``0.125 mm (0.5%)``."""
        unit = f" {self.unit}" if self.unit else ""
        shown = f"{self.sigma:.4g}{unit}"
        return f"{shown} ({self.given})" if self.given.endswith("%") else shown


@dataclass(frozen=True)
class BudgetSpec:
    """A budget: its ``inputs`` in the file's order, the ``draws`` per input (and for the
    total), the ``seed`` every draw is derived from, and the file it came from."""

    inputs: tuple[Input, ...]
    draws: int
    seed: int
    source: str = "budget"

    def manifest(self) -> dict[str, Any]:
        """What ties an output folder to this budget (JSON-able)."""
        return {
            "inputs": [[item.path, item.sigma] for item in self.inputs],
            "draws": self.draws,
            "seed": self.seed,
        }


def load_budget(
    path: str | os.PathLike[str],
    scene: Scene,
    draws: int | None = None,
    seed: int | None = None,
) -> BudgetSpec:
    """The budget file at ``path`` for ``scene`` (the truth, as the instrument measures
    it), checked; ``draws``/``seed`` (the command line's) replace the file's."""
    from glshade.scene.model import read_toml

    data = read_toml(Path(path), "budget file")
    return budget_from_dict(data, scene, str(path), draws, seed)


def budget_from_dict(
    data: Any,
    scene: Scene,
    source: str = "budget",
    draws: int | None = None,
    seed: int | None = None,
) -> BudgetSpec:
    """A budget from a budget file's tables (:func:`load_budget`), checked against
    ``scene``."""
    if not isinstance(data, dict):
        raise SceneError(source, "a TOML table with [uncertainty]", data)
    for key in data:
        if key not in TOP_KEYS:
            raise SceneError(
                f"{source}: {key}",
                "one of the keys draws, seed and the table [uncertainty] (unknown key)",
            )
    table = data.get(UNCERTAINTY_TABLE)
    if not isinstance(table, dict) or not table:
        raise SceneError(
            f"{source}: [{UNCERTAINTY_TABLE}]",
            'a table of at least one dotted parameter path = standard deviation ("camera.focal" '
            '= "0.5%")',
            None if table is None else table,
        )
    pairs = _flattened(table, source)
    inputs = []
    seen: set[str] = set()
    for path, sigma in pairs:
        if path in seen:
            raise SceneError(f"{source}: [uncertainty] {path}", "listed once", sigma)
        seen.add(path)
        inputs.append(checked_input(scene, path, sigma, source))
    return BudgetSpec(
        tuple(inputs),
        _count(data.get("draws", DEFAULT_DRAWS) if draws is None else draws, "draws", source),
        _seed(data.get("seed", DEFAULT_SEED) if seed is None else seed, source),
        source,
    )


def _flattened(table: dict[str, Any], source: str, prefix: str = "") -> list[tuple[str, Any]]:
    """``[uncertainty]``'s entries as ``(dotted path, σ)``: ``camera.focal = 1`` and
    ``[uncertainty.camera] focal = 1`` say the same."""
    pairs: list[tuple[str, Any]] = []
    for key, value in table.items():
        path = f"{prefix}{key}"
        if isinstance(value, dict):
            if not value:
                raise SceneError(
                    f"{source}: [uncertainty] {path}", "a parameter path = standard deviation"
                )
            pairs += _flattened(value, source, path + ".")
        else:
            pairs.append((path, value))
    return pairs


def checked_input(scene: Scene, path: str, sigma: Any, source: str = "budget") -> Input:
    """One ``path = σ`` of ``[uncertainty]`` checked against the schema and ``scene``."""
    field = f"{source}: [uncertainty] {path}"
    unit = _number_unit(scene, path, field)
    true = _true_value(scene, path, field)
    value, given = _sigma(sigma, unit, true, field)
    for sign in (-1.0, 1.0):
        believed = true + sign * RANGE_SIGMAS * value
        try:
            scene.with_calibration([(path, believed)])
        except SceneError as exc:
            shown = f"{value:.4g}{' ' + unit if unit else ''}"
            raise SceneError(
                field,
                f"a standard deviation whose draws stay in the parameter's range: σ {shown} "
                f"reaches {believed:.6g} within {RANGE_SIGMAS:g} σ of the true {true:.6g} "
                f"({exc.field}: must be {exc.allowed})",
            ) from None
    return Input(path, value, unit, true, given)


def _number_unit(scene: Scene, path: str, field: str) -> str:
    """The unit of the number at ``path``, or a SceneError where ``path`` names no
    parameter, or one that is not a real number (a vector without its ``[i]``)."""
    if not path or any(c.isspace() for c in path) or "." not in path:
        raise SceneError(
            field,
            "a dotted parameter path such as camera.focal or camera.position[0] "
            "(docs/scene-format.md)",
        )
    reg = registry()
    try:
        if path.endswith("]") and "[" in path:
            whole = path.partition("[")[0]
            param = reg.param(whole)
            if param.value_type != "vector":
                raise SceneError(whole, f"a vector parameter to take [i] of ({param.value_type})")
            scene.value(path)  # an index outside the vector: a SceneError naming it
            return param.unit
        entry = reg.entry(path)
        if entry is not None:
            return entry[0].unit
        param = reg.param(path)
    except SceneError as exc:
        named = field if exc.field == path else f"{field} ({exc.field})"
        raise SceneError(named, exc.allowed, exc.got) from None
    if param.value_type == "vector":
        raise SceneError(
            field,
            f"a number: one component of the vector, {path}[0] to {path}[{param.size - 1}]",
        )
    if param.value_type != "real":
        raise SceneError(field, f"the path of a parameter that is a number ({param.value_type})")
    return param.unit


def _true_value(scene: Scene, path: str, field: str) -> float:
    """The scene's value at ``path``: a finite number (a vector the scene leaves unset, a
    keyword such as ``"auto"``, are refused)."""
    value = scene.value(path)
    if value is None:
        whole = path.partition("[")[0]
        raise SceneError(
            field, f"a parameter the scene sets ({whole} is unset here: set it in the scene)"
        )
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise SceneError(field, "the path of a parameter whose value is a finite number", value)
    return float(value)


def _sigma(sigma: Any, unit: str, true: float, field: str) -> tuple[float, str]:
    """σ in the parameter's unit and as given."""
    words = SIGMA_WORDS.format(unit=f" ({unit})" if unit else "")
    if isinstance(sigma, bool) or not isinstance(sigma, (int, float, str)):
        raise SceneError(field, words, sigma)
    given = str(sigma).strip() if isinstance(sigma, str) else f"{sigma:g}"
    if isinstance(sigma, str) and given.endswith("%"):
        try:
            share = float(given[:-1])
        except ValueError:
            raise SceneError(field, words, sigma) from None
        if not (math.isfinite(share) and share >= 0.0):
            raise SceneError(field, words, sigma)
        if true == 0.0 and share > 0.0:
            raise SceneError(
                field, "a standard deviation in the parameter's unit (its true value is 0)", sigma
            )
        return share / 100.0 * abs(true), given
    if isinstance(sigma, str):
        from glshade.units import parse_quantity

        try:
            value = parse_quantity(given, unit, field)
        except SceneError:
            raise SceneError(field, words, sigma) from None
    else:
        value = float(sigma)
    if not (math.isfinite(value) and value >= 0.0):
        raise SceneError(field, words, sigma)
    return value, given


def _count(value: Any, key: str, source: str) -> int:
    lo, hi = DRAWS_RANGE
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise SceneError(f"{source}: {key}", f"an integer in [{lo}, {hi}]", value)
    return value


def _seed(value: Any, source: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= MAX_SEED:
        raise SceneError(f"{source}: seed", f"an integer in [0, {MAX_SEED}]", value)
    return value
