"""The formula grammar (groundwork of the ``formula`` surface kind, issue 11): what it
accepts, what it refuses and where, the exact derivatives, and GLSL that compiles and
agrees with the NumPy evaluation of the same tree."""

from __future__ import annotations

import math
import re

import moderngl
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from glshade.components.registry import registry
from glshade.components.surface.formula.grammar import (
    MAX_LENGTH,
    FormulaError,
    check_parameter_name,
    parse_formula,
)
from glshade.components.surface.formula.printers import GLSL_FUNCTIONS
from glshade.errors import SceneError
from glshade.scene import paper_scene

POINTS = np.array([[-3.0, -2.0], [-0.5, 1.5], [0.0, 0.0], [0.7, -4.0], [2.5, 3.25]])


@pytest.mark.parametrize(
    "text, params, expected",
    [
        (
            "0.0005*x^2 - 0.0002*z^2 + a*sin(z/b)",
            {"a": 0.002, "b": 5.0},
            lambda x, z: 0.0005 * x**2 - 0.0002 * z**2 + 0.002 * math.sin(z / 5.0),
        ),
        (
            "x^2 + 1",
            {},
            lambda x, z: x * x + 1,
        ),  # ^ is a power with a power's precedence, not x^(2+1)
        ("-x^2", {}, lambda x, z: -(x * x)),
        ("2^3^2 + 0*x", {}, lambda x, z: 512.0),  # right-associative, as **
        ("x**3 - z**-2 * 0 + x*z", {}, lambda x, z: x**3 + x * z),
        (
            "sqrt(x^2 + z^2 + 1) + exp(-x) + log(z^2 + 1)",
            {},
            lambda x, z: math.sqrt(x * x + z * z + 1) + math.exp(-x) + math.log(z * z + 1),
        ),
        (
            "abs(x) + min(x, z) + max(x, z, 0.5) + cos(x) * tan(z / 10)",
            {},
            lambda x, z: abs(x) + min(x, z) + max(x, z, 0.5) + math.cos(x) * math.tan(z / 10),
        ),
        ("+x - -z", {}, lambda x, z: x + z),
    ],
)
def test_accepted_formulas_evaluate_as_written(text, params, expected):
    f, _, _ = parse_formula(text, params).numpy
    got = f(POINTS[:, 0], POINTS[:, 1])
    want = [expected(x, z) for x, z in POINTS]
    assert got == pytest.approx(want, rel=1e-13, abs=1e-15)


@pytest.mark.parametrize(
    "text, params",
    [
        ("0.0005*x^2 - 0.0002*z^2 + a*sin(z/b)", {"a": 0.002, "b": 5.0}),
        ("sqrt(x^2 + z^2 + 1) * exp(-x/3) + log(z^2 + 2) / (1 + x^4)", {}),
        ("x^3*z - 2*x*z^2 + cos(x*z) + tan(z/7)", {}),
    ],
)
def test_derivatives_are_exact(text, params):
    f, fx, fz = parse_formula(text, params).numpy
    x, z = POINTS[:, 0], POINTS[:, 1]
    h = 1e-5
    assert fx(x, z) == pytest.approx((f(x + h, z) - f(x - h, z)) / (2 * h), rel=1e-7, abs=1e-9)
    assert fz(x, z) == pytest.approx((f(x, z + h) - f(x, z - h)) / (2 * h), rel=1e-7, abs=1e-9)


def test_the_sphere_written_as_a_formula_is_the_sphere():
    scene = paper_scene("sphere")
    sphere = registry().active(scene).surface
    radius = scene.surface.radius
    sag = parse_formula("-(x^2 + z^2) / (R + sqrt(R^2 - x^2 - z^2))", {"R": radius})
    f, fx, fz = sag.numpy
    x, z = POINTS[:, 0] * 5, POINTS[:, 1] * 5
    assert f(x, z) == pytest.approx(sphere.height(scene, x, z), rel=1e-14, abs=1e-15)
    normal = sphere.normal(scene, x, z, np.zeros_like(x), np.zeros_like(x))
    slopes = -normal[:, [0, 2]] / normal[:, [1]]  # n ∝ (-f_x, 1, -f_z)
    assert np.column_stack([fx(x, z), fz(x, z)]) == pytest.approx(slopes, rel=1e-12, abs=1e-15)


@pytest.mark.parametrize(
    "text, fragment, column",
    [
        ("x; y", "';'", 2),
        ("x}", "an unmatched '}'", 2),
        ("sin(x", "an unclosed '('", 4),
        ("x # }", "'# }'", 3),
        ("x\n+1", "a line break", 2),
        ('__import__("os").system("ls")', "'\"os\"'", 12),
        ("x.real", "'x.real'", 1),
        ("(lambda: 1)()", "the function 'lambda: 1'", 2),
        ("[x for x in z]", "'[x for x in z]'", 1),
        ("sum(x for x in z)", "the function 'sum'", 1),
        ("y + 1", "the undeclared name 'y'", 1),
        ("x + q", "the undeclared name 'q'", 5),
        ("foo(x)", "the function 'foo'", 1),
        ("sin(x, z)", "sin with 2 arguments", 1),
        ("max(x=1, z=2)", "keyword or starred arguments", 1),
        ("x @ z", "the operator '@'", 3),
        ("x // 2", "the operator '//'", 3),
        ("x < z", "the operator '<'", 3),
        ("not x", "the operator 'not'", 1),
        ("x if z else 1", "'x if z else 1'", 1),
        ("True + x", "'True'", 1),
        ("'s'", "\"'s'\"", 1),
        ("x**", "an unfinished expression", None),
        ("x*/z", "'/'", 3),
        ("\uff58 + 1", "the character '\uff58' (U+FF58)", 1),  # fullwidth x, NFKC of x
        ("\u0445 + 1", "the character '\u0445' (U+0445)", 1),  # Cyrillic
        ("x\u00a0+ 1", "the character '\\xa0' (U+00A0)", 2),  # no-break space
        ("x\x00", "the character '\\x00' (U+0000)", 2),
        ("x\r+1", "a line break", 2),
        ("sin(x)\u200b", "the character '\\u200b' (U+200B)", 7),
    ],
)
def test_refused_formulas_name_the_token_and_its_column(text, fragment, column):
    with pytest.raises(FormulaError) as info:
        parse_formula(text, {"b": 1.0})
    message = str(info.value)
    assert "\n" not in message and message.startswith("surface.expression: ")
    assert fragment in message, message
    if column is not None and "at column" in message:
        assert f"at column {column} is not allowed" in message, message
    assert "a formula may use numbers, x, z, the parameter b, + - * / ** ^" in message


def test_long_and_deep_input_is_refused():
    with pytest.raises(SceneError, match=f"at most {MAX_LENGTH} characters"):
        parse_formula("x+" * MAX_LENGTH + "1")
    with pytest.raises(SceneError, match="nested at most 40 deep"):
        parse_formula("sin(" * 60 + "x" + ")" * 60)
    with pytest.raises(SceneError, match="nested at most 40 deep"):
        parse_formula("-" * 41 + "x")
    parse_formula("sin(" * 39 + "x" + ")" * 39)
    with pytest.raises(SceneError):
        parse_formula("(" * 500 + "x" + ")" * 500)  # beyond Python's parser's nesting limit
    for empty in ("", "   ", None, 3.0):
        with pytest.raises(SceneError, match="a non-empty formula"):
            parse_formula(empty)


@pytest.mark.parametrize(
    "name",
    [
        "x",
        "z",
        "sin",
        "float",
        "uniform",
        "gl_Position",
        "a__b",
        "1a",
        "_a",
        "lambda",
        "a-b",
        "",
        "x" * 40,
        3,
    ],
)
def test_parameter_names_are_glsl_and_python_safe(name):
    with pytest.raises(SceneError, match="surface.parameters"):
        check_parameter_name(name)


def test_parameter_values_are_finite_numbers():
    for bad in (math.nan, math.inf, True, "2", [1.0]):
        with pytest.raises(SceneError, match="surface.parameters.a: must be a finite number"):
            parse_formula("a*x", {"a": bad})
    with pytest.raises(SceneError, match="surface.parameters: must be a table"):
        parse_formula("x", [1, 2])


_STATEMENT = re.compile(
    r"    real t\d+ = [A-Za-z0-9_ .()*/+\-,]+;|    return real3\([A-Za-z0-9_ .()*/+\-,]+\);"
)
_GLSL_WORDS = {
    "x",
    "z",
    "real",
    "real3",
    "return",
    "sqrt",
    "pow",
    "exp",
    "log",
    "sin",
    "cos",
    "tan",
    "abs",
    "min",
    "max",
    "sign",
    "formula_powi",
}


def _assert_safe_glsl(body: str, parameters: set[str]) -> None:
    """Every line a statement of a temporary, or the return; every name a temporary, a
    variable, a function of the grammar or a declared parameter's uniform."""
    for line in body.splitlines():
        assert _STATEMENT.fullmatch(line), line
        words = set(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", re.sub(r"\d+\.?\d*e[+-]?\d+", "", line)))
        words = {w for w in words if not re.fullmatch(r"t\d+", w)}
        assert words <= _GLSL_WORDS | parameters, words


@settings(max_examples=200, deadline=None)
@given(
    text=st.text(
        alphabet="xzab0123456789.+-*/^()_,; #{}[]:=<>!'\"\\ \nsqrtexplogincoanbmd", max_size=40
    )
)
def test_random_text_is_refused_or_prints_only_safe_glsl(text):
    try:
        formula = parse_formula(text, {"a": 1.5, "b": 2.0})
    except SceneError as exc:
        assert "\n" not in str(exc)
        return
    _assert_safe_glsl(formula.glsl(), {"u_surface_p_a", "u_surface_p_b"})


_PROGRAM = """
#version 450
#define real %(real)s
#define real2 %(real2)s
#define real3 %(real3)s
uniform real u_surface_p_a;
uniform real u_surface_p_b;
uniform vec4 u_box;   // x0, z0, dx, dz
out vec4 value;
%(functions)s
real3 formula_values(real x, real z) {
%(body)s
}
void main() {
    real x = real(u_box.x) + real(u_box.z) * real(floor(gl_FragCoord.x));
    real z = real(u_box.y) + real(u_box.w) * real(floor(gl_FragCoord.y));
    value = vec4(formula_values(x, z), 1.0);
}
"""
_VERTEX = """
#version 450
void main() { gl_Position = vec4(vec2(gl_VertexID & 1, gl_VertexID >> 1) * 4.0 - 1.0, 0.0, 1.0); }
"""
#: x0, z0, dx, dz of the 16 x 16 samples: x = 0, z = 0 and x = z are among them, exactly.
_BOX = (-3.0, -3.0, 0.375, 0.375)
_PARAMETERS = {"a": 0.002, "b": 5.0}


def _shader_values(gl_context, formula, precision: str = "fp32") -> np.ndarray:
    """``(f, f_x, f_z)`` (16, 16, 3) as the printed GLSL computes them on :data:`_BOX`."""
    double = precision == "fp64"
    source = _PROGRAM % {
        "real": "double" if double else "float",
        "real2": "dvec2" if double else "vec2",
        "real3": "dvec3" if double else "vec3",
        "functions": GLSL_FUNCTIONS,
        "body": formula.glsl(precision),
    }
    with gl_context.current() as ctx:
        program = ctx.program(vertex_shader=_VERTEX, fragment_shader=source)
        for name, value in _PARAMETERS.items():
            if f"u_surface_p_{name}" in program:
                program[f"u_surface_p_{name}"].value = value
        program["u_box"].value = _BOX
        target = ctx.texture((16, 16), 4, dtype="f4")
        fbo = ctx.framebuffer(color_attachments=[target])
        fbo.use()
        ctx.vertex_array(program, []).render(moderngl.TRIANGLES, vertices=3)
        pixels = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32).reshape(16, 16, 4)
        gl_context.park()
        fbo.release()
        target.release()
        program.release()
    return pixels[..., :3]


def _box_points() -> tuple[np.ndarray, np.ndarray]:
    cols, rows = np.meshgrid(np.arange(16), np.arange(16))
    return _BOX[0] + _BOX[2] * cols, _BOX[1] + _BOX[3] * rows


#: One formula per function of the grammar (and per kind of power), each with x and z
#: and, for abs, min and max, kinks on the samples of :data:`_BOX` (x = 0, x = z).
FUNCTION_FORMULAS = {
    "sqrt": "sqrt(x^2 + z^2 + 1) + 0.5*z",
    "exp": "exp(-x/3)*z",
    "log": "log(z^2 + 2)*x",
    "sin": "sin(x)*z",
    "cos": "cos(x*z/4)",
    "tan": "tan(z/9)*x",
    "abs": "abs(x)*z + abs(z - 1)",
    "min": "min(x, z) + min(x, 0.5*z, 1)*z",
    "max": "max(x, z) + max(x*z, z, -1)",
    "powers": "x^3 - z^5/7 + (x^2 + 1)^-2 + (z^2 + 1)^1.5 + (x^2 + 2)^(1/3)",
    "integer_powers": "(x^2 + 1)^-3 + (z^2 + 1)^1.5 + (x/3 + z/4)^7 - x^9/1000",
    "parameters": "0.0005*x^2 - 0.0002*z^2 + a*sin(z/b) + x^b",
}
_DOUBLE = ("sqrt", "abs", "min", "max", "integer_powers")


@pytest.mark.parametrize(
    "text",
    [
        *FUNCTION_FORMULAS.values(),
        "sqrt(x^2 + z^2 + 1) * exp(-x/3) + log(z^2 + 2) + abs(x) + max(x, z) + min(x, 0.5*z) + "
        "cos(x)*tan(z/9)",
        "((((x/4)^2 + z/5)^3 + 1)^2 + x)^2 / 100",  # nested powers: each base computed once
    ],
)
def test_the_printed_glsl_compiles_and_agrees_with_numpy(gl_context, text):
    formula = parse_formula(text, _PARAMETERS)
    pixels = _shader_values(gl_context, formula)
    x, z = _box_points()
    for index, function in enumerate(formula.numpy):
        want = function(x, z)
        assert np.array_equal(np.isnan(pixels[..., index]), np.isnan(want)), index
        assert pixels[..., index] == pytest.approx(
            want, rel=2e-5, abs=2e-5 * (1 + np.nanmax(np.abs(want))), nan_ok=True
        )


@pytest.mark.parametrize("name", _DOUBLE)
def test_the_double_precision_glsl_agrees_with_numpy(gl_context, name):
    formula = parse_formula(FUNCTION_FORMULAS[name], _PARAMETERS)
    pixels = _shader_values(gl_context, formula, "fp64")
    x, z = _box_points()
    for index, function in enumerate(formula.numpy):
        want = function(x, z).astype(np.float32)  # what the float render target holds
        assert pixels[..., index] == pytest.approx(want, rel=1e-6, abs=1e-6)


@pytest.mark.parametrize("name", sorted(FUNCTION_FORMULAS))
def test_each_function_s_derivatives_agree_with_finite_differences(name):
    """First derivatives against central differences of f, second against central
    differences of the exact first, at points off every kink."""
    formula = parse_formula(FUNCTION_FORMULAS[name], _PARAMETERS)
    (f, fx, fz), (fxx, fxz, fzz) = formula.numpy, formula.hessian
    x, z = np.array([-2.3, -0.7, 0.45, 1.3, 2.2]), np.array([1.7, -2.6, 0.8, 0.35, 2.9])
    h = 1e-5

    def dx(g):
        return (g(x + h, z) - g(x - h, z)) / (2 * h)

    def dz(g):
        return (g(x, z + h) - g(x, z - h)) / (2 * h)

    pairs = [(fx, dx(f)), (fz, dz(f)), (fxx, dx(fx)), (fxz, dz(fx)), (fzz, dz(fz))]
    pairs.append((fxz, dx(fz)))  # f_xz = f_zx
    for exact, estimate in pairs:
        finite = np.isfinite(estimate)  # x^b is NaN for x < 0, as GLSL's pow
        assert finite.sum() >= 3
        assert exact(x, z)[finite] == pytest.approx(estimate[finite], rel=1e-6, abs=1e-8)


def test_kinks_take_the_mean_of_the_one_sided_derivatives():
    """abs: sign(0) = 0; min, max: each argument gets half at a tie; the second
    derivative is 0 on both sides and on the kink (the delta dropped)."""
    zero = np.zeros(3)
    for text, slopes in (
        ("abs(x)", (0.0, 0.0)),
        ("min(x, z)", (0.5, 0.5)),
        ("max(x, z)", (0.5, 0.5)),
        ("max(2*x, -z)", (1.0, -0.5)),
        ("abs(x - z)^3", (0.0, 0.0)),
    ):
        formula = parse_formula(text)
        _, fx, fz = formula.numpy
        assert (fx(zero, zero).tolist(), fz(zero, zero).tolist()) == (
            [slopes[0]] * 3,
            [slopes[1]] * 3,
        )
        for second in formula.hessian[:1] if text != "abs(x - z)^3" else ():
            assert second(np.array([-1.0, 0.0, 1.0]), np.zeros(3)).tolist() == [0.0] * 3
    x = np.array([-1.0, -1e-9, 1e-9, 1.0])
    assert parse_formula("abs(x)").numpy[1](x, 0 * x).tolist() == [-1.0, -1.0, 1.0, 1.0]


def _polynomial(terms: int) -> tuple[str, dict[str, float]]:
    """``c0 + c1*x^1*z^0 + c2*x^0*z^1 + …``: all monomials by total degree."""
    names = [(a, total - a) for total in range(40) for a in range(total + 1)][:terms]
    text = " + ".join(f"c{i}*x^{a}*z^{b}" for i, (a, b) in enumerate(names))
    return text, {f"c{i}": 1e-3 / (i + 1) for i in range(terms)}


def test_sums_and_products_count_as_one_level_however_long():
    """A polynomial of 45 (or 120) terms is flat: its + and * chains are one level each."""
    for terms in (45, 120):
        text, parameters = _polynomial(terms)
        formula = parse_formula(text, parameters)
        x, z = np.array([0.3, -0.7]), np.array([1.1, 0.4])
        want = sum(
            parameters[f"c{i}"] * x**a * z**b
            for i, (a, b) in enumerate(
                [(a, t - a) for t in range(40) for a in range(t + 1)][:terms]
            )
        )
        assert formula.numpy[0](x, z) == pytest.approx(want, rel=1e-12)
    long_sum = "+".join(f"{i}*x" for i in range(300))
    assert parse_formula(long_sum).numpy[1](0.0, 0.0) == sum(range(300))
    parse_formula("*".join(["(x + 1)"] * 30) + " - (((((((x)))))))")
    parse_formula("-(-(-(x))) - x - (x - (z - (x - (z - 1))))")


@pytest.mark.parametrize(
    "text, fragment",
    [
        ("*".join(f"sin(x+{i})" for i in range(40)), "derivative along x takes more than"),
        (
            " + ".join("*".join(f"cos(x/{i + 2}+z/{j + 3})" for i in range(8)) for j in range(12)),
            "shader code (f, f_x, f_z) has",
        ),
    ],
)
def test_formulas_too_costly_to_differentiate_or_compile_are_refused(text, fragment):
    with pytest.raises(FormulaError) as info:
        parse_formula(text)
    message = str(info.value)
    assert fragment in message and "\n" not in message, message
    assert "is not allowed; " in message


@pytest.mark.parametrize(
    "text, fragment, column",
    [
        ("1" + "0" * 400 + "*x", "the number 100000000000...000000 (401 characters)", 1),
        ("1e999 * x", "the number 1e999", 1),
        ("x + 0x" + "f" * 40, "the number 0xffffffff", 5),
        ("1e39*x", "the number 1e39", 1),
        ("x ^ 100000", "the power 100000", 5),
        ("x^(2^7)", "the power 2^7", 4),
        ("(x^64)^64", "'(x^64)^64' (a power of 4096)", 1),
        ("x^64*x^64", "(a power of 128)", 1),
        ("1e30*x*1e30", "'1e30*x*1e30' (its constant factors make 1e+60)", 1),
        ("z + 3e38 + 3e38 + x", "(its constant terms make 6e+38)", 1),
        ("99999999^64*x", "'99999999^64' (beyond ±1.8e308)", 1),
        ("x + exp(100)", "'exp(100)' = 2.69e+43", 5),
        ("x + exp(1000)", "'exp(1000)' (beyond ±1.8e308)", 5),
        ("x + exp(exp(exp(100)))", "'exp(100)' = 2.69e+43", 13),
        ("x + log(-1)", "'log(-1)' at column 5", 5),
        ("x + 1/0", "'1/0' at column 5", 5),
        ("x/0", "a constant part that is not a finite real number", None),
        ("1e37*x^64", "its derivative f_x: the constant 6.4e+38", None),
    ],
)
def test_magnitudes_are_refused_naming_what_was_typed(text, fragment, column):
    with pytest.raises(FormulaError) as info:
        parse_formula(text)
    message = str(info.value)
    assert "\n" not in message and message.startswith("surface.expression: "), message
    assert fragment in message, message
    if column is not None:
        assert f"at column {column} is not allowed" in message, message
    assert len(message) < 300


@pytest.mark.parametrize(
    "value, shown",
    [(math.inf, "got inf"), (-math.inf, "got -inf"), (math.nan, "got nan"), (1e39, "got 1e+39")],
)
def test_parameters_beyond_single_precision_are_refused(value, shown):
    with pytest.raises(SceneError) as info:
        parse_formula("a*x", {"a": value})
    message = str(info.value)
    assert message.startswith("surface.parameters.a: must be a finite number within ±3.4e+38")
    assert message.endswith(shown) and "1e400, reads as inf" in message


def test_integral_float_powers_are_integer_powers():
    """x^2.0 is x*x (defined for x < 0), x^0.5 is sqrt(x); x^2.5 is NaN for x < 0, as
    GLSL's pow would be."""
    x = np.array([-2.0, 3.0])
    assert parse_formula("x^2.0").numpy[0](x, 0 * x).tolist() == [4.0, 9.0]
    assert "pow" not in parse_formula("x^2.0 + x^0.5").glsl()
    assert np.isnan(parse_formula("x^a", {"a": 2.0}).numpy[0](x, 0 * x)[0])


_LEAVES = ["x", "z", "a", "b", "0", "1", "2", "0.5", "7", "64", "65", "3e38", "1e-40", "1e39"]
_TOKENS = [*_LEAVES, "q", "1e999", "1" + "0" * 400, "0x1f", "2j", "+", "-", "*", "/", "^", "**"]
_TOKENS += ["(", ")", ",", " ", "sqrt", "exp", "log", "sin", "cos", "tan", "abs", "min", "max"]


def _grown(children):
    """One more level of the grammar around ``children``: an operator, a call, a sign."""
    return st.one_of(
        st.tuples(children, st.sampled_from(["+", "-", "*", "/", "^"]), children).map(
            lambda t: f"({t[0]}{t[1]}{t[2]})"
        ),
        st.tuples(
            st.sampled_from(["sqrt", "exp", "log", "sin", "cos", "tan", "abs"]), children
        ).map(lambda t: f"{t[0]}({t[1]})"),
        st.tuples(st.sampled_from(["min", "max"]), st.lists(children, min_size=2, max_size=3)).map(
            lambda t: f"{t[0]}({', '.join(t[1])})"
        ),
        children.map(lambda c: f"-{c}"),
    )


_FORMULAS = st.one_of(
    st.recursive(st.sampled_from(_LEAVES), _grown, max_leaves=10),
    st.lists(st.sampled_from(_TOKENS), min_size=1, max_size=25).map("".join),
)


@settings(max_examples=300, deadline=None, derandomize=True)
@given(text=_FORMULAS)
def test_formulas_of_the_grammar_s_tokens_give_a_surface_or_one_line(text):
    """Random formulas of the grammar's tokens (nested ones, and token soup): each is a
    surface whose GLSL, NumPy functions and bounds work, or a glshade error of one line,
    never another exception."""
    from glshade.components.surface.formula import _bounds
    from glshade.errors import GlshadeError

    x, z = np.array([-2.0, 0.0, 0.5, 3.0]), np.array([1.0, 0.0, -0.5, 2.0])
    try:
        formula = parse_formula(text, {"a": 1.5, "b": 2.0})
        _assert_safe_glsl(formula.glsl(), {"u_surface_p_a", "u_surface_p_b"})
        for function in (*formula.numpy, *formula.hessian):
            assert function(x, z).shape == (4,)
        formula.single_precision_overflow(x, z)
        _bounds(formula, (-30.0, 30.0, -40.0, 36.0), "fp32")
        formula.glsl("fp64")
    except GlshadeError as exc:
        message = str(exc)
        assert message and "\n" not in message and len(message) < 400, message


def test_the_token_limit_guards_python_s_parser(monkeypatch):
    """Beyond MAX_TOKENS the text is refused before Python's parser builds its tree (whose
    chains of operators end near 3000 in a row); checked here with a lowered limit, as
    the scene's 2000 characters hold at most 2000 tokens."""
    from glshade.components.surface.formula import grammar

    monkeypatch.setattr(grammar, "MAX_TOKENS", 100)
    parse_formula("+".join(["x"] * 50))
    with pytest.raises(SceneError, match="at most 100 tokens .* this one has 101"):
        parse_formula("+".join(["x"] * 51))


def test_single_precision_overflow_is_a_step_beyond_its_range():
    """A step whose float64 value is finite and beyond single precision's largest float
    is where an fp32 shader overflows; a pole or a domain's edge, infinite or NaN in
    float64 too, is the formula's own (``sqrt(x)``'s slope at 0)."""
    x = np.linspace(0.0, 100.0, 1001)
    step, wide, where = parse_formula("x^20*1e-30").single_precision_overflow(x, 0 * x)
    assert step == "x**20" and where.tolist() == (wide > 3.4028235e38).tolist() and where.any()
    assert parse_formula("x^19*1e-30").single_precision_overflow(x, 0 * x) is None
    assert np.isinf(parse_formula("sqrt(x)").numpy[1](0.0, 0.0))
    assert parse_formula("sqrt(x)").single_precision_overflow(x, 0 * x) is None
