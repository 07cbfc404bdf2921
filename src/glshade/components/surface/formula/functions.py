"""The formula's ``abs``, ``min`` and ``max`` in real arithmetic, and the almost-everywhere
derivatives of the kinks they make (loaded with the grammar, never at start-up).

SymPy's ``Abs``, ``Min`` and ``Max`` assume complex arguments where they cannot prove an
argument real (``abs(log(x))`` differentiates into ``re``, ``im`` and an unevaluated
``Derivative``), and their derivatives bring ``Heaviside`` and ``DiracDelta``, which
neither the shader nor the oracle evaluates. The classes here are real by construction
and their derivatives (:func:`derivative`, and SymPy's ``diff`` through ``fdiff``) use
``sign`` only:

- ``d abs(u) = sign(u) du``, with ``sign(0) = 0``;
- ``d min(a, b) = (1 - sign(a - b))/2 da + (1 + sign(a - b))/2 db`` and ``max``'s mirror
  image: at a tie each argument gets half (``H(0) = 1/2``);
- ``d sign(u) = 0``: the almost-everywhere value (the Dirac delta at ``u = 0`` is dropped).

At a kink the first derivative is therefore the mean of the two one-sided derivatives, and
the second derivative is the one of the smooth pieces (exact everywhere but on the kink,
a set of measure zero). :func:`almost_everywhere` maps SymPy's own ``Abs``, ``sign``,
``Min``, ``Max``, ``Heaviside`` and ``DiracDelta`` (which SymPy's simplification can bring
in, ``sqrt(x**2)`` is ``Abs(x)``) onto the same conventions.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence

import sympy
from sympy import Basic, Function, S

#: The uniform (and the SymPy symbol) of a formula's parameter ``name`` is this + name.
PARAMETER_PREFIX = "u_surface_p_"


class RealAbs(Function):
    """``|u|`` of a real ``u``; derivative ``sign(u)``."""

    nargs = 1

    @classmethod
    def eval(cls, u: Basic) -> Basic | None:
        if u.is_Number:
            return abs(u)
        return None

    def fdiff(self, argindex: int = 1) -> Basic:
        return RealSign(self.args[0])


class RealSign(Function):
    """``sign(u)`` of a real ``u`` (``sign(0) = 0``); derivative 0 almost everywhere."""

    nargs = 1

    @classmethod
    def eval(cls, u: Basic) -> Basic | None:
        if u.is_Number:
            return sympy.sign(u)
        return None

    def fdiff(self, argindex: int = 1) -> Basic:
        return S.Zero


def _half_step(difference: Basic, side: int) -> Basic:
    """``(1 + side * sign(difference)) / 2``: 1, 1/2 or 0, the share of a ``min``/``max``
    argument in its derivative."""
    return (1 + side * RealSign(difference)) / 2


def _finite_numbers(*args: Basic) -> bool:
    return all(arg.is_Number and arg.is_finite for arg in args)


class RealMin(Function):
    """``min(a, b)`` of two reals; at a tie each argument gets half of the derivative."""

    nargs = 2

    @classmethod
    def eval(cls, a: Basic, b: Basic) -> Basic | None:
        if _finite_numbers(a, b):
            return min(a, b)
        return None

    def fdiff(self, argindex: int = 1) -> Basic:
        a, b = self.args
        return _half_step(a - b, -1 if argindex == 1 else 1)


class RealMax(Function):
    """``max(a, b)`` of two reals; at a tie each argument gets half of the derivative."""

    nargs = 2

    @classmethod
    def eval(cls, a: Basic, b: Basic) -> Basic | None:
        if _finite_numbers(a, b):
            return max(a, b)
        return None

    def fdiff(self, argindex: int = 1) -> Basic:
        a, b = self.args
        return _half_step(a - b, 1 if argindex == 1 else -1)


def real_min(*args: Basic) -> Basic:
    """``min`` of two or more arguments, as nested :class:`RealMin`."""
    result = args[0]
    for arg in args[1:]:
        result = RealMin(result, arg)
    return result


def real_max(*args: Basic) -> Basic:
    """``max`` of two or more arguments, as nested :class:`RealMax`."""
    result = args[0]
    for arg in args[1:]:
        result = RealMax(result, arg)
    return result


def distinct_nodes(
    expressions: Iterable[Basic],
    operands: Callable[[Basic], Sequence[Basic]] = lambda node: node.args,
) -> list[Basic]:
    """The distinct nodes of ``expressions`` (symbols and numbers included), each after
    its ``operands``: a walk of the DAG, not of the tree (a derivative's tree can repeat
    a subexpression exponentially often; its DAG holds it once). Iterative."""
    done: set[Basic] = set()
    order: list[Basic] = []
    for expression in expressions:
        pending = [(expression, False)]
        while pending:
            node, expanded = pending.pop()
            if node in done:
                continue
            if expanded:
                done.add(node)
                order.append(node)
                continue
            pending.append((node, True))
            pending.extend((arg, False) for arg in reversed(operands(node)) if arg not in done)
    return order


#: SymPy's own classes that :func:`almost_everywhere` replaces.
_SYMPY_KINKS = (sympy.Abs, sympy.sign, sympy.Min, sympy.Max, sympy.Heaviside, sympy.DiracDelta)


def almost_everywhere(expression: Basic) -> Basic:
    """``expression`` with SymPy's ``Abs``, ``sign``, ``Min``, ``Max`` replaced by the real
    classes here, ``Heaviside(t)`` by ``(1 + sign(t))/2`` and ``DiracDelta`` by 0 (the
    conventions of the module docstring). SymPy brings ``Abs`` in by itself:
    ``sqrt(x**2)`` is ``Abs(x)`` for a real ``x``. Rebuilt node by node over the DAG."""
    order = distinct_nodes([expression])
    if not any(isinstance(node, _SYMPY_KINKS) for node in order):
        return expression
    rebuilt: dict[Basic, Basic] = {}
    for node in order:
        args = tuple(rebuilt[arg] for arg in node.args)
        new = node.func(*args) if args != node.args else node
        rebuilt[node] = _real_kink(new) if isinstance(new, _SYMPY_KINKS) else new
    return rebuilt[expression]


def _real_kink(node: Basic) -> Basic:
    """One of SymPy's :data:`_SYMPY_KINKS` as this module writes it."""
    args = node.args
    if isinstance(node, sympy.DiracDelta):
        return S.Zero
    if isinstance(node, sympy.Heaviside):
        return _half_step(args[0], 1)
    if isinstance(node, sympy.Abs):
        return RealAbs(*args)
    if isinstance(node, sympy.sign):
        return RealSign(*args)
    return (real_min if isinstance(node, sympy.Min) else real_max)(*args)


#: The node classes a formula, its derivatives and its Hessian may hold: what the GLSL
#: printer and the NumPy functions of :mod:`.grammar` know. Anything else is refused.
PRINTABLE = (
    sympy.Symbol,
    sympy.Integer,
    sympy.Rational,
    sympy.Float,
    type(S.Exp1),
    type(S.Pi),
    sympy.Add,
    sympy.Mul,
    sympy.Pow,
    sympy.exp,
    sympy.log,
    sympy.sin,
    sympy.cos,
    sympy.tan,
    RealAbs,
    RealSign,
    RealMin,
    RealMax,
)

#: NumPy's function for each class above whose name is not NumPy's.
NUMPY = {
    "RealAbs": "abs",
    "RealSign": "sign",
    "RealMin": "minimum",
    "RealMax": "maximum",
}


def unprintable(nodes: Iterable[Basic]) -> str | None:
    """The name of the first of ``nodes`` whose class is outside :data:`PRINTABLE`, or
    of a number that is not finite; None when every node is printable."""
    for node in nodes:
        if not isinstance(node, PRINTABLE):
            return type(node).__name__
        if node.is_Number and not math.isfinite(float(node)):
            return str(node)
    return None


def constant_value(expression: Basic) -> float:
    """The value of a constant ``expression`` (no free symbols) in float64 arithmetic:
    ``inf`` where it overflows, NaN where it is not a real number or holds anything else
    than :data:`PRINTABLE` (never SymPy's arbitrary precision: ``exp(exp(exp(100)))``
    costs nothing)."""
    try:
        return _value(expression)
    except (OverflowError, ZeroDivisionError, ValueError):
        return math.nan


_MATH: dict[type, Callable[..., float]] = {
    sympy.exp: math.exp,
    sympy.log: math.log,
    sympy.sin: math.sin,
    sympy.cos: math.cos,
    sympy.tan: math.tan,
    RealAbs: abs,
    RealSign: lambda u: float((u > 0) - (u < 0)) if u == u else math.nan,
    RealMin: min,
    RealMax: max,
}


def _value(e: Basic) -> float:
    if e.is_Rational:
        try:
            return float(e)
        except OverflowError:
            return math.copysign(math.inf, e.p)
    if isinstance(e, (sympy.Float, type(S.Exp1), type(S.Pi))):
        return float(e)
    if e.is_Add:
        return math.fsum(_value(a) for a in e.args)
    if e.is_Mul:
        return math.prod(_value(a) for a in e.args)
    if e.is_Pow:
        base, exponent = (_value(a) for a in e.args)
        try:
            return math.pow(base, exponent)
        except OverflowError:
            return math.inf
    function = _MATH.get(type(e))
    if function is None:
        return math.nan
    try:
        return float(function(*(_value(a) for a in e.args)))
    except OverflowError:
        return math.inf


class TooLarge(Exception):
    """A derivative would take more work than allowed (``work``: how much, at least)."""

    def __init__(self, work: int) -> None:
        super().__init__(work)
        self.work = work


def derivative(expression: Basic, symbol: Basic, max_work: int) -> Basic:
    """``∂expression/∂symbol`` of a tree of :data:`PRINTABLE` nodes, by the rules of
    calculus and the almost-everywhere conventions of this module (never SymPy's
    ``diff``, whose assumption queries cost seconds on a polynomial of 300 terms). Each
    distinct node is differentiated once; a :class:`TooLarge` as soon as the operands of
    the sums and products built add up beyond ``max_work`` (the cost of building, and of
    evaluating, the result)."""
    derivatives: dict[Basic, Basic] = {}
    depends: dict[Basic, bool] = {}
    work = [0]

    def varies(node: Basic) -> bool:
        known = depends.get(node)
        if known is None:
            known = depends[node] = node == symbol or any(varies(arg) for arg in node.args)
        return known

    def spend(amount: int) -> None:
        work[0] += amount
        if work[0] > max_work:
            raise TooLarge(work[0])

    def added(terms: Iterable[Basic]) -> Basic:
        """The sum of ``terms`` (products: their operands count), stopped at the limit."""
        kept = []
        for term in terms:
            spend(1 + (len(term.args) if term.is_Mul else 0))
            kept.append(term)
        return sympy.Add(*kept)

    def d(node: Basic) -> Basic:
        if not varies(node):
            return S.Zero
        known = derivatives.get(node)
        if known is None:
            spend(2)
            known = derivatives[node] = _rule(node, d, varies, added)
        return known

    return d(expression)


def _rule(
    node: Basic,
    d: Callable[[Basic], Basic],
    varies: Callable[[Basic], bool],
    added: Callable[[Iterable[Basic]], Basic],
) -> Basic:
    """The derivative of one node from its arguments' (``d``; ``added``: a sum that
    stops at the size limit)."""
    args = node.args
    if node.is_Symbol:
        return S.One
    if node.is_Add:
        return added(d(arg) for arg in args if varies(arg))
    if node.is_Mul:
        return added(
            sympy.Mul(*args[:i], d(arg), *args[i + 1 :])
            for i, arg in enumerate(args)
            if varies(arg)
        )
    if node.is_Pow:
        base, exponent = args
        if not varies(exponent):
            return exponent * base ** (exponent - 1) * d(base)
        return node * (d(exponent) * sympy.log(base) + exponent * d(base) / base)
    (u, *rest) = args
    if isinstance(node, sympy.exp):
        return node * d(u)
    if isinstance(node, sympy.log):
        return d(u) / u
    if isinstance(node, sympy.sin):
        return sympy.cos(u) * d(u)
    if isinstance(node, sympy.cos):
        return -sympy.sin(u) * d(u)
    if isinstance(node, sympy.tan):
        return (1 + node**2) * d(u)
    if isinstance(node, RealAbs):
        return RealSign(u) * d(u)
    if isinstance(node, RealSign):
        return S.Zero
    if isinstance(node, (RealMin, RealMax)):
        side = -1 if isinstance(node, RealMin) else 1
        (v,) = rest
        share = [_half_step(u - v, side), _half_step(u - v, -side)]
        return added(s * d(arg) for s, arg in zip(share, args, strict=True) if varies(arg))
    raise TypeError(f"no derivative rule for {type(node).__name__}")
