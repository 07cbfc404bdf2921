"""Surface formulas ``f(x, z)`` typed by a user, made safe (the groundwork of the
``formula`` surface kind, paper eq. 3; ``expression`` and ``parameters``).

The text is parsed with Python's :mod:`ast` in ``eval`` mode and only this grammar is
accepted: numbers, ``x``, ``z``, the declared parameters, ``+ - * /``, ``**`` and ``^``
(both power), unary ``+ -``, parentheses, and the functions
``sqrt exp log sin cos tan abs min max``. Anything else is refused with the offending
token and its column. The accepted tree is rebuilt as a SymPy expression node by node
(never ``eval``, ``sympify`` or ``parse_expr`` on the text), differentiated symbolically,
and printed as GLSL (SymPy's GLSL printer, with integer powers as products because GLSL's
``pow`` is undefined for a negative base) and as NumPy functions (``lambdify``) for the
oracle. No user text reaches the shader compiler or Python's evaluator: only SymPy's
printing of the rebuilt tree does, and parameter names become ``u_surface_p_<name>``.
"""

from __future__ import annotations

import ast
import io
import keyword
import math
import re
import tokenize
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from glshade.errors import GlshadeError, SceneError, printable

#: A parameter ``name`` of a formula is the uniform ``u_surface_p_<name>`` of its program.
PARAMETER_PREFIX = "u_surface_p_"

#: The longest expression and the deepest nesting accepted.
MAX_LENGTH = 2000
MAX_DEPTH = 40
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


class FormulaError(SceneError):
    """A formula outside the grammar: ``field: WHAT at column N is not allowed; a formula
    may use …`` (one line)."""

    def __init__(self, field_name: str, what: str, column: int | None, parameters) -> None:
        names = "".join(
            f"the parameter{'s' if len(parameters) > 1 else ''} {', '.join(parameters)}, "
            if parameters
            else ""
        )
        self.field, self.allowed, self.got, self.column = (
            field_name,
            _ALLOWED.format(params=names),
            what,
            column,
        )
        where = f" at column {column + 1}" if column is not None else ""
        GlshadeError.__init__(
            self,
            printable(
                f"{field_name}: {what}{where} is not allowed; a formula may use {self.allowed}"
            ),
        )


def _refuse(field_name: str, what: str, column: int | None, parameters) -> FormulaError:
    return FormulaError(field_name, what, column, list(parameters))


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


def _power_tokens(text: str, field_name: str, parameters) -> tuple[str, list[int]]:
    """``text`` with each ``^`` token written ``**`` (a token-level rewrite, so ``^``
    keeps the precedence of a power), and for each character of the result the column of
    the user's text it came from. Comments, strings and line breaks are refused here."""
    out: list[str] = []
    columns: list[int] = []
    previous_end = 0
    try:
        tokens = list(tokenize.generate_tokens(io.StringIO(text).readline))
    except (tokenize.TokenError, IndentationError, SyntaxError):
        what, column = _bracket_problem(text)
        raise _refuse(field_name, what, column, parameters) from None
    for token in tokens:
        if token.type in (tokenize.ENDMARKER, tokenize.NEWLINE) and not token.string.strip():
            continue
        (row, start), (_, end) = token.start, token.end
        if row != 1 or token.type == tokenize.NL:
            raise _refuse(field_name, "a line break", len(text.split("\n")[0]), parameters)
        if token.type in (tokenize.COMMENT, tokenize.STRING):
            raise _refuse(field_name, f"{token.string[:20]!r}", start, parameters)
        out.append(" " * (start - previous_end))
        columns.extend(range(previous_end, start))
        piece = "**" if token.type == tokenize.OP and token.string == "^" else token.string
        out.append(piece)
        columns.extend([start] * len(piece) if piece != token.string else range(start, end))
        previous_end = end
    return "".join(out), columns


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
    ``z`` in mm); ``parameters``: name -> value. Build with :func:`parse_formula`."""

    text: str
    parameters: tuple[tuple[str, float], ...]
    tree: Any = field(repr=False, compare=False)  # the SymPy expression

    @cached_property
    def symbols(self):
        import sympy

        return (
            sympy.Symbol("x", real=True),
            sympy.Symbol("z", real=True),
            *(sympy.Symbol(PARAMETER_PREFIX + name, real=True) for name, _ in self.parameters),
        )

    @cached_property
    def derivatives(self) -> tuple[object, object]:
        """``(∂f/∂x, ∂f/∂z)``, exact (SymPy)."""
        import sympy

        x, z = self.symbols[:2]
        return sympy.diff(self.tree, x), sympy.diff(self.tree, z)

    def glsl(self, precision: str = "fp32") -> tuple[str, str, str]:
        """GLSL expressions of ``f``, ``f_x``, ``f_z`` in the variables ``x``, ``z`` and the
        parameters ``u_surface_p_<name>`` (uniforms of the program). ``precision`` fp64 writes
        double literals and refuses what GLSL has no double version of (``exp``,
        ``log``, ``sin``, ``cos``, ``tan``, a non-integer power other than a square root)."""
        printer = _glsl_printer(precision)
        return tuple(printer.doprint(e) for e in (self.tree, *self.derivatives))

    @cached_property
    def hessian(self) -> tuple[Callable, ...]:
        """NumPy functions ``(f_xx, f_xz, f_zz)`` of ``(x, z)``: the curvature bounds of
        the first-hit search."""
        import sympy

        x, z = self.symbols[:2]
        fx, fz = self.derivatives
        return self._numpy_of(sympy.diff(fx, x), sympy.diff(fx, z), sympy.diff(fz, z))

    def _numpy_of(self, *expressions) -> tuple[Callable, ...]:
        """NumPy functions of ``(x, z)`` for SymPy ``expressions`` of this formula's
        symbols, the parameters bound (``lambdify`` prints the rebuilt tree, not user text)."""
        import sympy

        values = [value for _, value in self.parameters]
        modules = [{"Heaviside": _heaviside}, "numpy"]
        return tuple(
            _bound(sympy.lambdify(self.symbols, e, modules=modules), values) for e in expressions
        )

    @cached_property
    def numpy(self) -> tuple[Callable, ...]:
        """NumPy functions ``(f, f_x, f_z)`` of ``(x, z)`` (float64 arrays), with the
        parameters bound: the oracle's evaluation of the same tree."""
        return self._numpy_of(self.tree, *self.derivatives)


def _bound(compiled, values):
    def evaluate(x, z):
        x, z = np.asarray(x, np.float64), np.asarray(z, np.float64)
        with np.errstate(all="ignore"):
            return np.broadcast_to(
                np.asarray(compiled(x, z, *values), np.float64), np.broadcast(x, z).shape
            )

    return evaluate


def _heaviside(t, *_):
    return np.heaviside(t, 0.5)


def parse_formula(
    text: object, parameters: object = None, field_name: str = "surface.expression"
) -> Formula:
    """``text`` checked against the grammar and rebuilt as a SymPy expression, or a
    :class:`SceneError` naming ``field_name``, the offending token and its column."""
    params = _parameters(parameters)
    if not isinstance(text, str) or not text.strip():
        raise SceneError(field_name, "a non-empty formula in x and z", text)
    if len(text) > MAX_LENGTH:
        raise SceneError(
            field_name, f"a formula of at most {MAX_LENGTH} characters (this one has {len(text)})"
        )
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
    tree = _Builder(text, columns, params, field_name).build(expression.body, 0)
    formula = Formula(text, tuple(params.items()), tree)
    _check_defined(formula, field_name, params)
    return formula


def _check_defined(formula: Formula, field_name: str, params) -> None:
    """Refuse a formula whose constants SymPy folds to no real number (``0/0``, ``1/0``,
    ``log(0)``, ``sqrt(-1)``), in ``f`` or its derivatives."""
    import sympy

    bad = (sympy.nan, sympy.zoo, sympy.oo, -sympy.oo, sympy.I)
    expressions: tuple[Any, ...] = (formula.tree, *formula.derivatives)
    for expression in expressions:
        if any(expression.has(b) for b in bad):
            raise _refuse(
                field_name,
                "a constant part that is not a finite real number (0/0, 1/0, log(0), sqrt(-1))",
                None,
                params,
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
            or not math.isfinite(value)
        ):
            raise SceneError(f"surface.parameters.{name}", "a finite number", value)
        out[name] = float(value)
    return out


class _Builder:
    """The accepted AST, node by node, as SymPy; anything else is refused."""

    def __init__(
        self, text: str, columns: list[int], params: dict[str, float], field_name: str
    ) -> None:
        import sympy

        self.sympy, self.text, self.columns, self.params, self.field = (
            sympy,
            text,
            columns,
            params,
            field_name,
        )
        self.names = {
            "x": sympy.Symbol("x", real=True),
            "z": sympy.Symbol("z", real=True),
            **{name: sympy.Symbol(PARAMETER_PREFIX + name, real=True) for name in params},
        }
        self.functions = {
            "sqrt": sympy.sqrt,
            "exp": sympy.exp,
            "log": sympy.log,
            "sin": sympy.sin,
            "cos": sympy.cos,
            "tan": sympy.tan,
            "abs": sympy.Abs,
            "min": sympy.Min,
            "max": sympy.Max,
        }

    def refuse(self, node: ast.AST, what: str | None = None) -> SceneError:
        offset = getattr(node, "col_offset", 0)
        column = self.columns[min(offset, len(self.columns) - 1)] if self.columns else 0
        end = self.columns[
            min(max(getattr(node, "end_col_offset", offset + 1) - 1, 0), len(self.columns) - 1)
        ]
        shown = what or repr(self.text[column : end + 1][:20])
        return _refuse(self.field, shown, column, self.params)

    def build(self, node: ast.AST, depth: int):
        if depth > MAX_DEPTH:
            raise SceneError(self.field, f"a formula nested at most {MAX_DEPTH} deep")
        sp = self.sympy
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                raise self.refuse(node)
            if isinstance(node.value, float) and not math.isfinite(node.value):
                raise self.refuse(node, "a number too large")
            return (
                sp.Integer(node.value)
                if isinstance(node.value, int)
                else sp.Float(repr(node.value), 17)
            )
        if isinstance(node, ast.Name):
            if node.id not in self.names:
                raise self.refuse(node, f"the undeclared name {node.id!r}")
            return self.names[node.id]
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            operand = self.build(node.operand, depth + 1)
            return -operand if isinstance(node.op, ast.USub) else operand
        if isinstance(node, ast.BinOp) and isinstance(
            node.op, (ast.Add, ast.Sub, ast.Mult, ast.Div, ast.Pow)
        ):
            left, right = self.build(node.left, depth + 1), self.build(node.right, depth + 1)
            if isinstance(node.op, ast.Pow) and right.is_number and abs(float(right)) > 64:
                raise self.refuse(node.right, "a power beyond 64")
            op = node.op
            return (
                left + right
                if isinstance(op, ast.Add)
                else left - right
                if isinstance(op, ast.Sub)
                else left * right
                if isinstance(op, ast.Mult)
                else left / right
                if isinstance(op, ast.Div)
                else left**right
            )
        if isinstance(node, ast.Call):
            return self.call(node, depth)
        if isinstance(node, (ast.BinOp, ast.BoolOp, ast.Compare, ast.UnaryOp)):
            raise self.refuse_operator(node)
        raise self.refuse(node)

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

    def call(self, node: ast.Call, depth: int):
        if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
            raise self.refuse(node.func, f"the function {ast.unparse(node.func)[:20]!r}")
        if node.keywords or any(isinstance(a, ast.Starred) for a in node.args):
            raise self.refuse(node, "keyword or starred arguments")
        lo, hi = FUNCTIONS[node.func.id]
        if not lo <= len(node.args) <= hi:
            raise self.refuse(node, f"{node.func.id} with {len(node.args)} arguments")
        args = [self.build(a, depth + 1) for a in node.args]
        return self.functions[node.func.id](*args)


#: What GLSL 4.5 offers only in single precision.
_FLOAT_ONLY = ("exp", "log", "sin", "cos", "tan")


def _glsl_printer(precision: str = "fp32"):
    """SymPy's GLSL printer, with integer powers written as products (GLSL's ``pow`` is
    undefined for a negative base), Heaviside as ``step`` and numbers at full precision
    (``LF`` double literals for fp64)."""
    from sympy.printing.glsl import GLSLPrinter

    suffix = "LF" if precision == "fp64" else ""

    class Printer(GLSLPrinter):
        def _print_Pow(self, expr):
            base, exponent = expr.as_base_exp()
            if exponent.is_Integer and 1 <= abs(int(exponent)) <= 64:
                product = "*".join([f"({self._print(base)})"] * abs(int(exponent)))
                return f"({product})" if exponent > 0 else f"(1.0{suffix}/({product}))"
            if (
                exponent.is_Rational and exponent.q == 2 and abs(exponent.p) <= 63
            ):  # sqrt(b)^p, exact in fp64
                product = "*".join([f"sqrt({self._print(base)})"] * abs(int(exponent.p)))
                return f"({product})" if exponent > 0 else f"(1.0{suffix}/({product}))"
            if suffix:
                raise _no_double("a non-integer power")
            return super()._print_Pow(expr)

        def _print_Function(self, expr):
            if suffix and type(expr).__name__ in _FLOAT_ONLY:
                raise _no_double(type(expr).__name__)
            return super()._print_Function(expr)

        def _print_Heaviside(self, expr):
            return f"step(0.0{suffix}, {self._print(expr.args[0])})"

        def _print_Float(self, expr):
            return repr(float(expr)) + suffix

        def _print_Integer(self, expr):
            return f"{int(expr)}.0{suffix}"

        def _print_Rational(self, expr):
            return f"({expr.p}.0{suffix}/{expr.q}.0{suffix})"

    return Printer({"use_operators": True})


def _no_double(what: str) -> SceneError:
    return SceneError(
        "render.precision",
        f"fp32 for this formula: GLSL has no double-precision version of {what} "
        "(fp64 formulas may use + - * /, integer powers, sqrt, abs, min and max)",
    )
