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
        ("1e999 * x", "a number too large", 1),
        ("x ^ 100", "a power beyond 64", 5),
        ("x**", "an unfinished expression", None),
        ("x*/z", "'/'", 3),
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


_GLSL_WORDS = {
    "x",
    "z",
    "sqrt",
    "exp",
    "log",
    "sin",
    "cos",
    "tan",
    "abs",
    "min",
    "max",
    "step",
    "sign",
    "pow",
}


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
    for code in formula.glsl():
        assert re.fullmatch(r"[A-Za-z0-9_ .()*/+\-,?:<>=!]*", code), code
        words = set(re.findall(r"[A-Za-z_][A-Za-z0-9_]*", re.sub(r"\d+\.?\d*e[+-]?\d+", "", code)))
        assert words <= _GLSL_WORDS | {"u_surface_p_a", "u_surface_p_b"}, words


_PROGRAM = """
#version 450
uniform float u_surface_p_a;
uniform float u_surface_p_b;
uniform vec4 u_box;   // x0, z0, dx, dz
out vec4 value;
void main() {
    float x = u_box.x + u_box.z * floor(gl_FragCoord.x);
    float z = u_box.y + u_box.w * floor(gl_FragCoord.y);
    value = vec4(%s, %s, %s, 1.0);
}
"""
_VERTEX = """
#version 450
void main() { gl_Position = vec4(vec2(gl_VertexID & 1, gl_VertexID >> 1) * 4.0 - 1.0, 0.0, 1.0); }
"""


@pytest.mark.parametrize(
    "text",
    [
        "0.0005*x^2 - 0.0002*z^2 + a*sin(z/b)",
        "x^3 - z^5 / 7 + x^-2 * 0.01",  # integer powers of negative numbers: products, not pow()
        "sqrt(x^2 + z^2 + 1) * exp(-x/3) + log(z^2 + 2) + abs(x) + max(x, z) + min(x, 0.5*z) + "
        "cos(x)*tan(z/9)",
    ],
)
def test_the_printed_glsl_compiles_and_agrees_with_numpy(gl_context, text):
    formula = parse_formula(text, {"a": 0.002, "b": 5.0})
    with gl_context.current() as ctx:
        program = ctx.program(vertex_shader=_VERTEX, fragment_shader=_PROGRAM % formula.glsl())
        for name, value in (("u_surface_p_a", 0.002), ("u_surface_p_b", 5.0)):
            if name in program:
                program[name].value = value
        program["u_box"].value = (-3.1, -2.9, 0.37, 0.41)
        target = ctx.texture((16, 16), 4, dtype="f4")
        fbo = ctx.framebuffer(color_attachments=[target])
        fbo.use()
        ctx.vertex_array(program, []).render(moderngl.TRIANGLES, vertices=3)
        pixels = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32).reshape(16, 16, 4)
        gl_context.park()
        fbo.release()
        target.release()
        program.release()
    cols, rows = np.meshgrid(np.arange(16), np.arange(16))
    x, z = -3.1 + 0.37 * cols, -2.9 + 0.41 * rows
    for index, function in enumerate(formula.numpy):
        want = function(x, z)
        assert pixels[..., index] == pytest.approx(
            want, rel=2e-5, abs=2e-5 * (1 + np.abs(want).max())
        )
