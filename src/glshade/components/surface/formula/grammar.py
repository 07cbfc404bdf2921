"""Surface formulas ``f(x, z)`` typed by a user, made safe (the groundwork of the
``formula`` surface kind, paper eq. 3; ``expression`` and ``parameters``).

The text is parsed with Python's :mod:`ast` in ``eval`` mode and only this grammar is
accepted: numbers, ``x``, ``z``, the declared parameters, ``+ - * /``, ``**`` and ``^``
(both power), unary ``+ -``, parentheses, and the functions
``sqrt exp log sin cos tan abs min max``. Anything else is refused with the offending
token and its column. The accepted tree is rebuilt as a SymPy expression node by node
(never ``eval``, ``sympify`` or ``parse_expr`` on the text), differentiated symbolically
(``abs``, ``min`` and ``max`` are real functions whose kinks get the almost-everywhere
conventions of :mod:`.functions`), and printed as GLSL and as NumPy functions for the
oracle (:mod:`.printers`). No user text reaches the shader compiler or Python's
evaluator: only the printing of the rebuilt tree does, and parameter names become
``u_surface_p_<name>``.

Limits (each refusal is one line naming what was typed and what is allowed): the length
(:data:`MAX_LENGTH` characters), the size (:data:`MAX_TOKENS` tokens), the nesting
(:data:`MAX_DEPTH`: a chain of ``+ -`` or of ``* /`` is one level however long, so a
polynomial of hundreds of terms is flat; a call, a power, a unary sign nests), the
powers (:data:`MAX_POWER`), the magnitude of every number, parameter and constant the
formula folds to (:data:`MAX_MAGNITUDE`, single precision's range), the work of each
derivative (:data:`MAX_DERIVATIVE_WORK`) and the size of the shader code
(:data:`MAX_OPERATIONS`).
"""

from __future__ import annotations

import ast
import io
import keyword
import math
import re
import tokenize
import warnings
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from glshade.errors import GlshadeError, SceneError, printable
from glshade.params import MAX_TEXT

if TYPE_CHECKING:  # SymPy is loaded by the first formula parsed
    from sympy import Basic

#: A parameter ``name`` of a formula is the uniform ``u_surface_p_<name>`` of its program.

#: The longest expression (characters: a scene's limit on a text value) and the most
#: tokens (numbers, names, operators, brackets) accepted. The token limit keeps every
#: chain of operators well inside what Python's parser builds (about 3000 in a row),
#: should the text limit grow.
MAX_LENGTH = MAX_TEXT
MAX_TOKENS = 3_000
#: The deepest nesting: calls, powers and unary signs inside each other (a chain of
#: ``+ -`` or of ``* /``, parentheses included, is one level).
MAX_DEPTH = 40
#: The largest magnitude of a power's exponent (also of what powers of powers fold to).
MAX_POWER = 64
#: The largest magnitude of a number, a parameter or a constant the formula (or its
#: derivative) folds to: single precision's largest float, the range of a program's
#: uniforms and of an fp32 literal.
MAX_MAGNITUDE = float(np.finfo(np.float32).max)
#: The most operations of the shader code of f, f_x and f_z together (GLSL statements'
#: operands, a transcendental function or a power by squaring counting 8): the shader
#: compiler's time grows with them, about 5 ms each on llvmpipe (a polynomial of 200
#: terms is about 2700).
MAX_OPERATIONS = 3_000
#: The most operations building one derivative may take (first or second): SymPy's time
#: and the NumPy evaluation's grow with them.
MAX_DERIVATIVE_WORK = 20_000
#: The functions of the grammar and how many arguments each takes.
FUNCTIONS: dict[str, tuple[int, int]] = {
    "sqrt": (1, 1),
    "exp": (1, 1),
    "log": (1, 1),
    "sin": (1, 1),
    "cos": (1, 1),
    "tan": (1, 1),
    "abs": (1, 1),
    "min": (2, 8),
    "max": (2, 8),
}
VARIABLES = ("x", "z")
#: A parameter's name: a letter, then letters, digits or underscores (GLSL-safe).
_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,31}$")
_GLSL_RESERVED = frozenset(
    [
        "attribute",
        "const",
        "uniform",
        "varying",
        "buffer",
        "shared",
        "coherent",
        "volatile",
        "restrict",
        "readonly",
        "writeonly",
        "layout",
        "centroid",
        "flat",
        "smooth",
        "noperspective",
        "patch",
        "sample",
        "break",
        "continue",
        "do",
        "for",
        "while",
        "switch",
        "case",
        "default",
        "if",
        "else",
        "subroutine",
        "in",
        "out",
        "inout",
        "float",
        "double",
        "int",
        "void",
        "bool",
        "true",
        "false",
        "invariant",
        "precise",
        "discard",
        "return",
        "mat2",
        "mat3",
        "mat4",
        "vec2",
        "vec3",
        "vec4",
        "dvec2",
        "dvec3",
        "dvec4",
        "struct",
        "real",
        "input",
        "output",
        "asm",
        "class",
        "union",
        "enum",
        "typedef",
        "template",
        "this",
        "goto",
        "inline",
        "noinline",
        "public",
        "static",
        "extern",
        "external",
        "interface",
        "long",
        "short",
        "half",
        "fixed",
        "unsigned",
        "superp",
        "sizeof",
        "cast",
        "namespace",
        "using",
        "step",
        "sign",
        "pow",
    ]
)
_ALLOWED = (
    "numbers, x, z, {params}+ - * / ** ^, parentheses and sqrt exp log sin cos tan abs min max"
)
_RANGE = f"numbers, parameters and the constants they fold to must lie within ±{MAX_MAGNITUDE:.3g}"


class FormulaError(SceneError):
    """A formula outside the grammar or its limits: ``field: WHAT at column N is not
    allowed; a formula may use …`` (one line; ``allowed`` replaces the grammar's list
    where a limit, not the grammar, refuses)."""

    def __init__(
        self,
        field_name: str,
        what: str,
        column: int | None,
        parameters: Sequence[str],
        allowed: str | None = None,
    ) -> None:
        names = "".join(
            f"the parameter{'s' if len(parameters) > 1 else ''} {', '.join(parameters)}, "
            if parameters
            else ""
        )
        self.field, self.allowed, self.got, self.column = (
            field_name,
            _ALLOWED.format(params=names) if allowed is None else allowed,
            what,
            column,
        )
        where = f" at column {column + 1}" if column is not None else ""
        rule = f"a formula may use {self.allowed}" if allowed is None else allowed
        GlshadeError.__init__(
            self, printable(f"{field_name}: {what}{where} is not allowed; {rule}")
        )


def _refuse(
    field_name: str,
    what: str,
    column: int | None,
    parameters: Iterable[str],
    allowed: str | None = None,
) -> FormulaError:
    return FormulaError(field_name, what, column, list(parameters), allowed)


def abbreviated(text: str, limit: int = 24) -> str:
    """``text`` as an error message shows it: whole up to ``limit`` characters, else its
    start and end with its length."""
    if len(text) <= limit:
        return text
    return f"{text[:12]}...{text[-6:]} ({len(text)} characters)"


def check_parameter_name(name: object, field_name: str = "surface.parameters") -> str:
    """A declared parameter's name, or a SceneError: letters, digits and underscores, not
    ``x``/``z``, a function, a Python keyword or a GLSL reserved word."""
    if (
        not isinstance(name, str)
        or not _NAME.match(name)
        or name in VARIABLES
        or name in FUNCTIONS
        or keyword.iskeyword(name)
        or name in _GLSL_RESERVED
        or "__" in name
        or name.startswith("gl_")
    ):
        raise SceneError(
            field_name,
            "parameter names of a letter then letters, digits or single underscores, "
            "none of x, z, the functions or a reserved word",
            name,
        )
    return name


def _check_characters(text: str, field_name: str, parameters: Iterable[str]) -> None:
    """Refuse, at its column, the first character outside printable ASCII, tab and line
    break: a control character, and every look-alike (``ｘ``, which Python would read as
    ``x``, a Cyrillic ``х``, a no-break space)."""
    for column, char in enumerate(text):
        if char == "\r":
            raise _refuse(field_name, "a line break", column, parameters)
        if not (" " <= char <= "~" or char in "\t\n"):
            what = f"the character {char!r} (U+{ord(char):04X})"
            raise _refuse(field_name, what, column, parameters)


def _power_tokens(text: str, field_name: str, parameters: Iterable[str]) -> tuple[str, list[int]]:
    """``text`` with each ``^`` token written ``**`` (a token-level rewrite, so ``^``
    keeps the precedence of a power), and for each character of the result the column of
    the user's text it came from. Comments, strings, line breaks, more than
    :data:`MAX_TOKENS` tokens and numbers beyond :data:`MAX_MAGNITUDE` are refused here
    (before Python's parser builds a tree of them)."""
    out: list[str] = []
    columns: list[int] = []
    previous_end = 0
    try:
        tokens = list(tokenize.generate_tokens(io.StringIO(text).readline))
    except (tokenize.TokenError, IndentationError, SyntaxError):
        what, column = _bracket_problem(text)
        raise _refuse(field_name, what, column, parameters) from None
    if len(tokens) > MAX_TOKENS + 2:  # + NEWLINE and ENDMARKER
        raise SceneError(
            field_name,
            f"a formula of at most {MAX_TOKENS} tokens (numbers, names, operators, "
            f"brackets; this one has {len(tokens) - 2})",
        )
    for token in tokens:
        if token.type in (tokenize.ENDMARKER, tokenize.NEWLINE) and not token.string.strip():
            continue
        (row, start), (_, end) = token.start, token.end
        if row != 1 or token.type == tokenize.NL:
            raise _refuse(field_name, "a line break", len(text.split("\n")[0]), parameters)
        if token.type in (tokenize.COMMENT, tokenize.STRING):
            raise _refuse(field_name, f"{token.string[:20]!r}", start, parameters)
        if token.type == tokenize.NUMBER and not _literal_magnitude(token.string) <= MAX_MAGNITUDE:
            shown = abbreviated(token.string)
            raise _refuse(field_name, f"the number {shown}", start, parameters, _RANGE)
        out.append(" " * (start - previous_end))
        columns.extend(range(previous_end, start))
        piece = "**" if token.type == tokenize.OP and token.string == "^" else token.string
        out.append(piece)
        columns.extend([start] * len(piece) if piece != token.string else range(start, end))
        previous_end = end
    return "".join(out), columns


def _literal_magnitude(token: str) -> float:
    """The magnitude of a number token (``inf`` beyond float64; 0 for what the builder
    refuses anyway: an imaginary literal, a malformed one)."""
    digits = token.replace("_", "").lower()
    try:
        if digits.startswith(("0x", "0o", "0b")):
            return float(int(digits, 0))
        return 0.0 if digits.endswith("j") else abs(float(digits))
    except OverflowError:
        return math.inf
    except ValueError:
        return 0.0


def _bracket_problem(text: str) -> tuple[str, int | None]:
    """The first unmatched bracket of ``text`` (what tokenize stumbled on)."""
    pairs, opened = {")": "(", "]": "[", "}": "{"}, []
    for column, char in enumerate(text):
        if char in "([{":
            opened.append((char, column))
        elif char in pairs:
            if not opened or opened[-1][0] != pairs[char]:
                return f"an unmatched {char!r}", column
            opened.pop()
    if opened:
        return f"an unclosed {opened[-1][0]!r}", opened[-1][1]
    return "an unfinished expression", None


def _token_at(text: str, column: int) -> str:
    """The token of ``text`` that starts at ``column`` (a name or number, else one
    character), for error messages."""
    word = re.match(r"[A-Za-z0-9_.]+|\S", text[column:])
    return word.group(0)[:20] if word else "the end"


@dataclass(frozen=True)
class Formula:
    """A parsed, checked formula. ``text``: as the user wrote it (in mm, of ``x`` and
    ``z`` in mm); ``parameters``: name -> value; ``tree``, ``gradient`` and ``second``:
    ``f``, ``(f_x, f_z)`` and ``(f_xx, f_xz, f_zz)`` as SymPy expressions (exact, with the
    almost-everywhere conventions of :mod:`.functions` at kinks). Build with
    :func:`parse_formula`."""

    text: str
    parameters: tuple[tuple[str, float], ...]
    tree: Any = field(repr=False, compare=False)
    gradient: tuple[Any, Any] = field(repr=False, compare=False)
    second: tuple[Any, Any, Any] = field(repr=False, compare=False)

    @property
    def symbols(self) -> tuple[Any, ...]:
        """``(x, z, u_surface_p_<name>...)``: the arguments of the NumPy functions."""
        return _symbols(tuple(name for name, _ in self.parameters))

    def glsl(self, precision: str = "fp32") -> str:
        """The body of the GLSL function ``real3 formula_values(real x, real z)`` that
        returns ``(f, f_x, f_z)``: one statement per distinct node, in the variables ``x``,
        ``z`` and the parameters ``u_surface_p_<name>`` (uniforms of the program), calling
        :data:`.printers.GLSL_FUNCTIONS`. ``precision`` fp64 writes double literals and
        refuses what GLSL has no double version of (``exp``, ``log``, ``sin``, ``cos``,
        ``tan``, a non-integer power other than a square root)."""
        from glshade.components.surface.formula.printers import glsl_body

        names = tuple(name for name, _ in self.parameters)
        return glsl_body((self.tree, *self.gradient), precision, names)

    @cached_property
    def hessian(self) -> tuple[Callable, ...]:
        """NumPy functions ``(f_xx, f_xz, f_zz)`` of ``(x, z)`` (float64): the curvature
        bounds of the first-hit search; 0 across a kink (almost everywhere)."""
        return self._functions(*self.second)

    @cached_property
    def numpy(self) -> tuple[Callable, ...]:
        """NumPy functions ``(f, f_x, f_z)`` of ``(x, z)`` (float64 arrays), with the
        parameters bound: the oracle's evaluation of the same tree."""
        return self._functions(self.tree, *self.gradient)

    def single_precision_overflow(
        self, x: NDArray[np.float64], z: NDArray[np.float64]
    ) -> tuple[str, np.ndarray, np.ndarray] | None:
        """Where an fp32 shader overflows computing ``f``, ``f_x``, ``f_z`` at ``(x, z)``:
        the first step (as SymPy writes it) whose value is finite but beyond
        :data:`MAX_MAGNITUDE`, its values and where; None where no step is."""
        from glshade.components.surface.formula.printers import first_beyond

        inputs: list[ArrayLike] = [x, z, *(value for _, value in self.parameters)]
        found = first_beyond(self.symbols, (self.tree, *self.gradient), inputs, MAX_MAGNITUDE)
        return None if found is None else (str(found[0]), found[1], found[2])

    def _functions(self, *expressions: Basic) -> tuple[Callable, ...]:
        from glshade.components.surface.formula.printers import numpy_function

        values = [value for _, value in self.parameters]
        return tuple(_bound(numpy_function(self.symbols, e), values) for e in expressions)


def _symbols(names: tuple[str, ...]) -> tuple[Any, ...]:
    import sympy

    from glshade.components.surface.formula.functions import PARAMETER_PREFIX

    return (
        sympy.Symbol("x", real=True),
        sympy.Symbol("z", real=True),
        *(sympy.Symbol(PARAMETER_PREFIX + name, real=True) for name in names),
    )


def _bound(
    compiled: Callable[..., Any], values: Sequence[float]
) -> Callable[[ArrayLike, ArrayLike], NDArray[np.float64]]:
    def evaluate(x: ArrayLike, z: ArrayLike) -> NDArray[np.float64]:
        x, z = np.asarray(x, np.float64), np.asarray(z, np.float64)
        with np.errstate(all="ignore"):
            return np.broadcast_to(
                np.asarray(compiled(x, z, *values), np.float64), np.broadcast(x, z).shape
            )

    return evaluate


def parse_formula(
    text: object, parameters: object = None, field_name: str = "surface.expression"
) -> Formula:
    """``text`` checked against the grammar and its limits and rebuilt as a SymPy
    expression with its exact gradient, or a :class:`SceneError` naming ``field_name``,
    the offending token and its column."""
    params = _parameters(parameters)
    if not isinstance(text, str) or not text.strip():
        raise SceneError(field_name, "a non-empty formula in x and z", text)
    if len(text) > MAX_LENGTH:
        raise SceneError(
            field_name, f"a formula of at most {MAX_LENGTH} characters (this one has {len(text)})"
        )
    _check_characters(text, field_name, params)
    source, columns = _power_tokens(text, field_name, params)
    try:
        with (
            warnings.catch_warnings()
        ):  # "invalid decimal literal" and friends: the error below says it
            warnings.simplefilter("ignore")
            expression = ast.parse(source.strip() or "()", mode="eval")
    except SyntaxError as exc:
        offset = (exc.offset or 1) - 1
        if offset >= len(columns) or text.rstrip()[-1] in "+-*/^(,":
            raise _refuse(field_name, "an unfinished expression", None, params) from None
        column = columns[offset]
        raise _refuse(field_name, repr(_token_at(text, column)), column, params) from None
    except (RecursionError, MemoryError, ValueError):
        raise SceneError(field_name, f"a formula nested at most {MAX_DEPTH} deep") from None
    from glshade.components.surface.formula.functions import almost_everywhere

    tree = almost_everywhere(_Builder(text, columns, params, field_name).build(expression.body, 0))
    _check_tree(tree, field_name, params, "")
    x, z = _symbols(tuple(params))[:2]
    gradient = tuple(_derivative(tree, s, field_name, params, "first") for s in (x, z))
    for name, derivative in zip(("f_x", "f_z"), gradient, strict=True):
        _check_tree(derivative, field_name, params, f"its derivative {name}: ")
    _check_program((tree, *gradient), field_name, params)
    orders = ((0, x), (0, z), (1, z))  # f_xx, f_xz, f_zz
    second = tuple(_derivative(gradient[i], s, field_name, params, "second") for i, s in orders)
    _check_printable(second, field_name, params, "its second derivatives: ")
    return Formula(text, tuple(params.items()), tree, gradient, second)


def _derivative(
    expression: Basic, symbol: Basic, field_name: str, params: Iterable[str], order: str
) -> Basic:
    """``∂expression/∂symbol`` (:func:`.functions.derivative`), or a refusal where it
    takes more than :data:`MAX_DERIVATIVE_WORK` operations to build."""
    from glshade.components.surface.formula.functions import (
        TooLarge,
        almost_everywhere,
        derivative,
    )

    try:
        return almost_everywhere(derivative(expression, symbol, MAX_DERIVATIVE_WORK))
    except TooLarge as exc:
        raise _refuse(
            field_name,
            f"a formula whose {order} derivative along {symbol} takes more than "
            f"{exc.work} operations",
            None,
            params,
            f"derivatives of at most {MAX_DERIVATIVE_WORK} operations (a product of many "
            "factors of x and z, or functions nested in them, grows fastest)",
        ) from None


def _check_program(expressions: Iterable[Basic], field_name: str, params: Iterable[str]) -> None:
    """Refuse a formula whose shader code (``f``, ``f_x``, ``f_z``) has more than
    :data:`MAX_OPERATIONS` operations: the time the shader compiler takes grows with it."""
    from glshade.components.surface.formula.printers import operations

    count = operations(expressions)
    if count > MAX_OPERATIONS:
        raise _refuse(
            field_name,
            f"a formula whose shader code (f, f_x, f_z) has {count} operations",
            None,
            params,
            f"at most {MAX_OPERATIONS} (a polynomial of about 200 terms; the shader "
            "compiler's time grows with them)",
        )


def _check_tree(tree: Basic, field_name: str, params: Iterable[str], where: str) -> None:
    """Refuse a tree holding what is not a finite real number (``x/0``), anything the
    printers do not know, a constant beyond :data:`MAX_MAGNITUDE` or a power beyond
    :data:`MAX_POWER` (what the rebuilt tree and its derivatives fold to). Each distinct
    node is looked at once."""
    import sympy

    from glshade.components.surface.formula.functions import distinct_nodes

    nodes = distinct_nodes([tree])
    bad = {sympy.nan, sympy.zoo, sympy.oo, -sympy.oo, sympy.I}
    if any(node in bad for node in nodes):
        raise _refuse(
            field_name,
            f"{where}a constant part that is not a finite real number (0/0, 1/0, log(0), sqrt(-1))",
            None,
            params,
        )
    _check_printable([tree], field_name, params, where, nodes)
    for node in nodes:
        if node.is_Number and abs(float(node)) > MAX_MAGNITUDE:
            raise _refuse(
                field_name, f"{where}the constant {float(node):.3g}", None, params, _RANGE
            )
        if node.is_Pow and node.exp.is_Number and abs(float(node.exp)) > MAX_POWER:
            raise _refuse(
                field_name,
                f"{where}{abbreviated(str(node), 40)} (what its powers fold to)",
                None,
                params,
                f"powers of at most {MAX_POWER} in magnitude",
            )


def _check_printable(
    trees: Iterable[Basic],
    field_name: str,
    params: Iterable[str],
    where: str,
    nodes: list[Basic] | None = None,
) -> None:
    """Refuse trees holding a node the printers do not know (what SymPy's simplification
    might bring in): nothing unmapped reaches the GLSL or the NumPy functions."""
    from glshade.components.surface.formula.functions import distinct_nodes, unprintable

    name = unprintable(distinct_nodes(trees) if nodes is None else nodes)
    if name is not None:
        raise _refuse(
            field_name,
            f"{where}a formula that SymPy rewrites with {abbreviated(name)}",
            None,
            params,
            "the shader and the oracle evaluate only the grammar's functions",
        )


def _parameters(parameters: object) -> dict[str, float]:
    if parameters is None:
        return {}
    if not isinstance(parameters, dict):
        raise SceneError("surface.parameters", "a table of name = number", parameters)
    out = {}
    for name, value in parameters.items():
        check_parameter_name(name)
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not abs(value) <= MAX_MAGNITUDE  # also NaN
        ):
            raise SceneError(
                f"surface.parameters.{name}",
                f"a finite number within ±{MAX_MAGNITUDE:.3g} (a number beyond ±1.8e308, "
                "such as 1e400, reads as inf)",
                value if isinstance(value, (bool, int, float)) else abbreviated(repr(value)),
            )
        out[name] = float(value)
    return out


class _Builder:
    """The accepted AST, node by node, as SymPy; anything else is refused."""

    def __init__(
        self, text: str, columns: list[int], params: dict[str, float], field_name: str
    ) -> None:
        import sympy

        from glshade.components.surface.formula import functions

        self.sympy, self.text, self.columns, self.params, self.field = (
            sympy,
            text,
            columns,
            params,
            field_name,
        )
        self.names = dict(zip(("x", "z", *params), _symbols(tuple(params)), strict=True))
        self.functions = {
            "sqrt": sympy.sqrt,
            "exp": sympy.exp,
            "log": sympy.log,
            "sin": sympy.sin,
            "cos": sympy.cos,
            "tan": sympy.tan,
            "abs": functions.RealAbs,
            "min": functions.real_min,
            "max": functions.real_max,
        }
        self.constant_value = functions.constant_value

    def span(self, node: ast.AST) -> tuple[int, str]:
        """The column of ``node`` in the user's text and the text it spans."""
        offset = getattr(node, "col_offset", 0)
        column = self.columns[min(offset, len(self.columns) - 1)] if self.columns else 0
        end = self.columns[
            min(max(getattr(node, "end_col_offset", offset + 1) - 1, 0), len(self.columns) - 1)
        ]
        return column, self.text[column : end + 1]

    def refuse(self, node: ast.AST, what: str | None = None) -> SceneError:
        column, text = self.span(node)
        return _refuse(self.field, what or repr(text[:20]), column, self.params)

    def build(self, node: ast.AST, depth: int) -> Basic:
        if depth > MAX_DEPTH:
            column, text = self.span(node)
            raise _refuse(
                self.field,
                f"{abbreviated(text)!r}, nested {depth} deep,",
                column,
                self.params,
                f"a formula nested at most {MAX_DEPTH} deep (a call, a power or a unary sign "
                "inside another; a chain of + - or of * / counts once however long)",
            )
        result = self.node(node, depth)
        if not result.free_symbols:
            self.check_constant(node, result)
        return result

    def check_constant(self, node: ast.AST, value: Basic) -> None:
        """A constant part (no x, z or parameter) must be a finite real number within
        :data:`MAX_MAGNITUDE` (checked in float64, never SymPy's arbitrary precision)."""
        number = self.constant_value(value)
        if math.isfinite(number) and abs(number) <= MAX_MAGNITUDE:
            return
        column, text = self.span(node)
        what = repr(abbreviated(text))
        if math.isnan(number):
            allowed = "every constant part must be a finite real number (no 0/0, 1/0, "
            allowed += "log(0), sqrt(-1))"
        else:
            what += f" = {number:.3g}" if math.isfinite(number) else " (beyond ±1.8e308)"
            allowed = _RANGE
        raise _refuse(self.field, what, column, self.params, allowed)

    def check_folded(
        self, node: ast.AST, operation: Callable[..., Basic], operands: list[Basic], what: str
    ) -> None:
        """The constant operands of a chain (``1e30*x*1e30``), which SymPy folds into one
        number, within :data:`MAX_MAGNITUDE`."""
        constants = [operand for operand in operands if not operand.free_symbols]
        if len(constants) < 2 or len(constants) == len(operands):
            return  # a whole constant chain is checked as a constant node
        number = self.constant_value(operation(*constants))
        if abs(number) <= MAX_MAGNITUDE:
            return
        column, text = self.span(node)
        made = f"{number:.3g}" if math.isfinite(number) else "more than ±1.8e308"
        raise _refuse(
            self.field,
            f"{abbreviated(text)!r} (its constant {what} make {made})",
            column,
            self.params,
            _RANGE,
        )

    def node(self, node: ast.AST, depth: int) -> Basic:
        sp = self.sympy
        if isinstance(node, ast.Constant):
            return self.number(node)
        if isinstance(node, ast.Name):
            if node.id not in self.names:
                raise self.refuse(node, f"the undeclared name {abbreviated(node.id)!r}")
            return self.names[node.id]
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            operand = self.build(node.operand, depth + 1)
            return -operand if isinstance(node.op, ast.USub) else operand
        if isinstance(node, ast.BinOp) and isinstance(node.op, (ast.Add, ast.Sub)):
            terms = [s * self.build(t, depth + 1) for t, s in _chain(node, (ast.Add, ast.Sub))]
            self.check_folded(node, sp.Add, terms, "terms")
            return sp.Add(*terms)
        if isinstance(node, ast.BinOp) and isinstance(node.op, (ast.Mult, ast.Div)):
            factors = [self.build(f, depth + 1) ** s for f, s in _chain(node, (ast.Mult, ast.Div))]
            self.check_folded(node, sp.Mul, factors, "factors")
            return self.checked_powers(node, sp.Mul(*factors))
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow):
            return self.power(node, depth)
        if isinstance(node, ast.Call):
            return self.call(node, depth)
        if isinstance(node, (ast.BinOp, ast.BoolOp, ast.Compare, ast.UnaryOp)):
            raise self.refuse_operator(node)
        raise self.refuse(node)

    def number(self, node: ast.Constant) -> Basic:
        value = node.value
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.refuse(node)
        if not abs(value) <= MAX_MAGNITUDE:
            column, text = self.span(node)
            raise _refuse(
                self.field, f"the number {abbreviated(text)}", column, self.params, _RANGE
            )
        sp = self.sympy
        return sp.Integer(value) if isinstance(value, int) else sp.Float(repr(value), 17)

    def power(self, node: ast.BinOp, depth: int) -> Basic:
        left, right = self.build(node.left, depth + 1), self.build(node.right, depth + 1)
        if not right.free_symbols and abs(self.constant_value(right)) > MAX_POWER:
            column, text = self.span(node.right)
            raise _refuse(
                self.field,
                f"the power {abbreviated(text)}",
                column,
                self.params,
                f"powers of at most {MAX_POWER} in magnitude",
            )
        if right.is_Float and float(2 * right).is_integer():  # x^2.0 is x^2, x^0.5 sqrt(x)
            right = self.sympy.Rational(int(2 * right), 2)
        return self.checked_powers(node, left**right)

    def checked_powers(self, node: ast.AST, result: Basic) -> Basic:
        """``result``, unless SymPy folded powers of powers (``(x^64)^64``, ``x^64*x^64``)
        beyond :data:`MAX_POWER`."""
        for part in (result, *result.args) if result.is_Mul else (result,):
            if part.is_Pow and part.exp.is_Number and abs(float(part.exp)) > MAX_POWER:
                column, text = self.span(node)
                raise _refuse(
                    self.field,
                    f"{abbreviated(text)!r} (a power of {float(part.exp):g})",
                    column,
                    self.params,
                    f"powers of at most {MAX_POWER} in magnitude",
                )
        return result

    def refuse_operator(self, node: ast.AST) -> FormulaError:
        """An operator outside the grammar, pointed at (not the whole expression)."""
        operands = [child for child in ast.iter_child_nodes(node) if isinstance(child, ast.expr)]
        if isinstance(node, ast.UnaryOp):
            start, stop = node.col_offset, operands[0].col_offset
        else:
            start, stop = operands[0].end_col_offset or 0, operands[1].col_offset
        source = "".join(
            self.text[c] if c < len(self.text) else " " for c in self.columns[start:stop]
        )
        token = source.strip(" ()") or source.strip() or "?"
        column = (
            self.columns[start] + source.index(token[0])
            if token[0] in source
            else self.columns[start]
        )
        return _refuse(self.field, f"the operator {token!r}", column, self.params)

    def call(self, node: ast.Call, depth: int) -> Basic:
        if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
            raise self.refuse(node.func, f"the function {ast.unparse(node.func)[:20]!r}")
        if node.keywords or any(isinstance(a, ast.Starred) for a in node.args):
            raise self.refuse(node, "keyword or starred arguments")
        lo, hi = FUNCTIONS[node.func.id]
        if not lo <= len(node.args) <= hi:
            raise self.refuse(node, f"{node.func.id} with {len(node.args)} arguments")
        args = [self.build(a, depth + 1) for a in node.args]
        return self.functions[node.func.id](*args)


def _chain(node: ast.AST, operators: tuple[type, ...]) -> list[tuple[ast.AST, int]]:
    """The operands of a chain of ``operators`` (``+ -`` or ``* /``, through parentheses)
    in order, each with its sign: 1, or -1 for a subtracted term or a divisor. Iterative:
    a chain of thousands of terms is one level of nesting, not thousands."""
    operands: list[tuple[ast.AST, int]] = []
    pending: list[tuple[ast.AST, int]] = [(node, 1)]
    while pending:
        current, sign = pending.pop()
        if isinstance(current, ast.BinOp) and isinstance(current.op, operators):
            inverse = isinstance(current.op, (ast.Sub, ast.Div))
            pending.append((current.right, -sign if inverse else sign))
            pending.append((current.left, sign))
        else:
            operands.append((current, sign))
    return operands
