"""The checked SymPy trees of a formula (``f``, its gradient, its Hessian) turned into
GLSL statements (the shader) and into NumPy operations (the oracle); loaded with the
grammar, never at start-up.

Both see only the node classes of :data:`.functions.PRINTABLE` (the grammar refuses any
other first) and both take each distinct node once, in an order computed once
(:func:`postorder`): one GLSL statement ``real tN = …;`` or one NumPy operation per
node. A derivative that repeats a subexpression a thousand times costs it once, and
neither the shader compiler nor Python ever meets a nesting deeper than one node's
operands. Integer powers are products (GLSL's ``pow`` is undefined for a negative base),
of a base computed once; other powers are ``pow``, NaN for a negative base on both sides.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Callable, Iterable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from glshade.components.surface.formula.functions import (
    NUMPY,
    PARAMETER_PREFIX,
    distinct_nodes,
)
from glshade.errors import SceneError

if TYPE_CHECKING:
    from sympy import Basic

#: GLSL the formula's statements call (``real``: float or double, the program's
#: precision): ``b^n`` for ``1 <= n <= 127`` by squaring, exact in sign for a negative base.
GLSL_FUNCTIONS = """real formula_powi(real b, int n) {
    real result = 1.0;
    for (int i = 0; i < 7 && n > 0; ++i) {
        if ((n & 1) != 0) result *= b;
        n >>= 1;
        b *= b;
    }
    return result;
}"""

#: What GLSL 4.5 offers only in single precision.
_FLOAT_ONLY = ("exp", "log", "sin", "cos", "tan")
#: GLSL's names for the grammar's functions (the others keep theirs).
_GLSL_CALLS = {"RealAbs": "abs", "RealSign": "sign", "RealMin": "min", "RealMax": "max"}
#: Sums and products with more operands than this are written as balanced trees.
_BALANCE = 16
#: What one printed statement may be: a temporary of an expression of names, numbers,
#: operators and brackets; and the names it may use besides temporaries and parameters.
_STATEMENT = re.compile(
    r"    real t\d+ = [A-Za-z0-9_ .()*/+\-,]+;|    return real3\([A-Za-z0-9_ .()*/+\-,]+\);"
)
_NUMBER = re.compile(r"(?<![A-Za-z0-9_])\d+(\.\d*)?(e[+-]?\d+)?(LF)?")
_NAMES = frozenset(
    [
        "x",
        "z",
        "real",
        "real3",
        "return",
        "sqrt",
        "pow",
        "formula_powi",
        *_FLOAT_ONLY,
        *_GLSL_CALLS.values(),
    ]
)


def postorder(expressions: Iterable[Any]) -> list[Any]:
    """The distinct nodes of ``expressions`` other than symbols and numbers, each after
    the nodes it is computed from (a walk of the DAG, iterative)."""
    return [node for node in distinct_nodes(expressions, _operands) if not node.is_Atom]


#: The weight of a transcendental function or of a power by squaring (a loop) against an
#: addition or multiplication, in :func:`operations`.
_HEAVY = 8


def operations(expressions: Iterable[Any]) -> int:
    """The size of the program that computes ``expressions`` (GLSL statements or NumPy
    operations): each distinct node counts its operands, a transcendental function or a
    power beyond the 4th :data:`_HEAVY` (what the shader compiler's time grows with)."""
    total = 0
    for node in postorder(expressions):
        total += len(_operands(node))
        if type(node).__name__ in _FLOAT_ONLY or (
            node.is_Pow and not (node.exp.is_Rational and abs(node.exp.p) <= 4)
        ):
            total += _HEAVY
    return total


def _operands(node: Basic) -> tuple[Any, ...]:
    """What a node is computed from (a power's rational exponent is part of its
    operation)."""
    if node.is_Pow and node.exp.is_Rational:
        return (node.base,)
    return node.args


# ---------------------------------------------------------------------------------- GLSL
def glsl_body(expressions: Sequence[Basic], precision: str, parameters: tuple[str, ...]) -> str:
    """The body of ``real3 formula_values(real x, real z)``: one statement per distinct
    node of ``expressions`` (``f``, ``f_x``, ``f_z``), then ``return real3(f, f_x, f_z);``.
    Each line is checked to be such a statement holding only temporaries, ``x``, ``z``,
    the ``parameters``' uniforms, the functions of the grammar and of
    :data:`GLSL_FUNCTIONS`, numbers, operators and brackets (a bug, never user text,
    would fail the check)."""
    suffix = "LF" if precision == "fp64" else ""
    names: dict[Any, str] = {}

    def text(node: Basic) -> str:
        if node in names:
            return names[node]
        if node.is_Symbol:
            return str(node)
        value = repr(float(node)) + suffix
        return f"({value})" if value.startswith("-") else value

    lines: list[str] = []
    for node in postorder(expressions):
        names[node] = f"t{len(lines)}"
        lines.append(f"    real {names[node]} = {_glsl_operation(node, text, suffix)};")
    lines.append(f"    return real3({', '.join(text(e) for e in expressions)});")
    allowed = _NAMES | {PARAMETER_PREFIX + name for name in parameters}
    for line in lines:
        used = set(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", _NUMBER.sub(" ", line)))
        if not _STATEMENT.fullmatch(line) or not {u for u in used if not _temporary(u)} <= allowed:
            raise RuntimeError(f"formula printed as unexpected GLSL: {line[:200]!r}")
    return "\n".join(lines)


def _temporary(name: str) -> bool:
    return name[0] == "t" and name[1:].isdigit()


def _glsl_operation(node: Basic, text: Callable[[Any], str], suffix: str) -> str:
    """The GLSL expression of one node, its operands written by ``text``."""
    if node.is_Add:
        return _joined([text(a) for a in node.args], " + ")
    if node.is_Mul:
        return _joined([text(a) for a in node.args], "*")
    if node.is_Pow:
        return _glsl_power(node, text, suffix)
    name = type(node).__name__
    if name in _FLOAT_ONLY:
        if suffix:
            raise _no_double(name)
        return f"{name}({text(node.args[0])})"
    if name in _GLSL_CALLS:
        return f"{_GLSL_CALLS[name]}({', '.join(text(a) for a in node.args)})"
    raise RuntimeError(f"no GLSL for {name}")


def _joined(operands: list[str], operator: str) -> str:
    """``operands`` joined by ``operator``, as a balanced tree of brackets where long."""
    if len(operands) <= _BALANCE:
        return operator.join(operands)
    half = len(operands) // 2
    return f"({_joined(operands[:half], operator)}){operator}({_joined(operands[half:], operator)})"


def _glsl_power(node: Basic, text: Callable[[Any], str], suffix: str) -> str:
    """An integer or half-integer power as products of the base (or of its square root),
    others as ``pow`` (single precision only)."""
    exponent = node.exp
    if exponent.is_Rational and exponent.q in (1, 2):
        base = text(node.base)
        root = base if exponent.q == 1 else f"sqrt({base})"
        count = abs(int(exponent.p))
        power = "*".join([root] * count) if count <= 4 else f"formula_powi({root}, {count})"
        return power if exponent > 0 else f"1.0{suffix}/({power})"
    if suffix:
        raise _no_double("a non-integer power")
    return f"pow({text(node.base)}, {text(exponent)})"


def _no_double(what: str) -> SceneError:
    return SceneError(
        "render.precision",
        f"fp32 for this formula: GLSL has no double-precision version of {what} "
        "(fp64 formulas may use + - * /, integer powers, sqrt, abs, min and max)",
    )


# --------------------------------------------------------------------------------- NumPy
def numpy_function(symbols: Sequence[Basic], expression: Basic) -> Callable[..., Any]:
    """``expression`` as a NumPy function of float64 arrays for ``symbols``. ``abs min
    max`` and their ``sign`` are NumPy's ``abs minimum maximum sign``; a power other than
    an integer or half-integer one is NaN for a negative base, as GLSL's ``pow``."""
    program = _Program(symbols, [expression])
    return lambda *inputs: program.outputs(program.run(inputs))[0]


def first_beyond(
    symbols: Sequence[Basic],
    expressions: Sequence[Basic],
    inputs: Iterable[ArrayLike],
    limit: float,
) -> tuple[Any, np.ndarray, np.ndarray] | None:
    """The first node of ``expressions``, in the shader's order of evaluation, whose
    float64 value at ``inputs`` (arrays for ``symbols``) is finite and beyond ``limit``
    in magnitude: ``(node, its values, where)``, or None. With single precision's
    largest float as ``limit``: the step where an fp32 shader overflows (an infinity or
    NaN that float64 also finds, a pole or a domain's edge, is the formula's own)."""
    program = _Program(symbols, expressions)
    with np.errstate(all="ignore"):
        for node, value in zip(program.nodes, program.steps_of(program.run(inputs)), strict=True):
            beyond = np.isfinite(value) & (np.abs(value) > limit)
            if np.any(beyond):
                return node, np.asarray(value), beyond
    return None


class _Program:
    """The NumPy operations (float64) of ``expressions``: one per distinct node, in the
    order of :func:`postorder` (the GLSL statements' order), each from the slots of its
    operands (the ``symbols``' inputs, constants, earlier nodes)."""

    def __init__(self, symbols: Sequence[Basic], expressions: Sequence[Basic]) -> None:
        self.slots: dict[Any, int] = {symbol: i for i, symbol in enumerate(symbols)}
        self.inputs = len(symbols)
        self.constants: list[float] = []
        self.nodes = postorder(expressions)
        self.steps: list[tuple[Callable[..., Any], tuple[int, ...]]] = []
        for node in self.nodes:
            operands = tuple(self.slot(arg) for arg in _operands(node))
            self.slots[node] = self.inputs + len(self.steps)
            self.steps.append((_numpy_operation(node), operands))
        self.results = [self.slot(e) for e in expressions]

    def slot(self, node: Basic) -> int:
        """The slot of ``node``; a number gets one of its own (negative), filled once."""
        if node not in self.slots:
            self.slots[node] = -1 - len(self.constants)
            self.constants.append(float(node))
        return self.slots[node]

    def run(self, inputs: Iterable[ArrayLike]) -> list[Any]:
        """The inputs, then the value of every step."""
        values: list[Any] = [np.asarray(v, np.float64) for v in inputs]
        with np.errstate(all="ignore"):
            for operation, operands in self.steps:
                values.append(operation(*(self.value(values, i) for i in operands)))
        return values

    def value(self, values: list[Any], slot: int) -> Any:
        return values[slot] if slot >= 0 else self.constants[-1 - slot]

    def outputs(self, values: list[Any]) -> list[Any]:
        return [self.value(values, slot) for slot in self.results]

    def steps_of(self, values: list[Any]) -> list[Any]:
        return values[self.inputs :]


def _numpy_operation(node: Basic) -> Callable[..., Any]:
    """The NumPy operation of one node."""
    if node.is_Add:
        return lambda *terms: _balanced(np.add, terms)
    if node.is_Mul:
        return lambda *factors: _balanced(np.multiply, factors)
    if node.is_Pow:
        exponent = node.exp
        if exponent == 1 / 2:
            return np.sqrt
        if exponent.is_Rational and exponent.q in (1, 2):
            power = float(exponent)  # NaN for a negative base where half-integer
            return lambda base: np.power(base, power)
        if exponent.is_Rational:
            fraction = float(exponent)
            return lambda base: _real_pow(base, fraction)
        return _real_pow
    function = _NUMPY_FUNCTIONS.get(type(node).__name__)
    if function is None:
        raise RuntimeError(f"no NumPy operation for {type(node).__name__}")
    return function


def _balanced(operation: np.ufunc, operands: Sequence[Any]) -> Any:
    """``operands`` combined by ``operation`` in the order the GLSL is written
    (:func:`_joined`): left to right, long chains as a balanced tree of halves."""
    if len(operands) <= _BALANCE:
        return functools.reduce(operation, operands)
    half = len(operands) // 2
    return operation(_balanced(operation, operands[:half]), _balanced(operation, operands[half:]))


_NUMPY_FUNCTIONS: dict[str, Callable[..., Any]] = {
    "exp": np.exp,
    "log": np.log,
    "sin": np.sin,
    "cos": np.cos,
    "tan": np.tan,
    **{name: getattr(np, numpy_name) for name, numpy_name in NUMPY.items()},
}


def _real_pow(base: ArrayLike, exponent: ArrayLike) -> NDArray[Any]:
    """``base ** exponent`` as GLSL's ``pow``: undefined (NaN) for a negative base, even
    where the exponent happens to be a whole number."""
    result = np.power(base, exponent)
    return np.where(np.asarray(base) < 0, np.asarray(np.nan, result.dtype), result)
