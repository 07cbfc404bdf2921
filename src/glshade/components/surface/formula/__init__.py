"""A base surface given as a formula ``y = f(x, z)`` (paper eq. 3; ``kind =
"formula"``, ``expression``, ``parameters``).

The expression is checked and rebuilt by :mod:`.grammar` (never evaluated as text); the
GLSL that computes ``(f, f_x, f_z)`` (:mod:`.printers`: one statement per distinct node)
is a template variable of ``formula.glsl``, so each formula compiles one program, and its
parameters are uniforms. The first hit is a march that cannot pass the first crossing
(the library's ``freeform.glsl``), bracketed by the slab ``lo <= y - f <= hi`` and driven
by a bound ``K`` on ``|f''|`` along horizontal directions. ``lo``, ``hi`` and ``K`` come
from the formula, its exact Hessian and the change of its exact gradient across each
cell, sampled on a 129 x 129 grid over the region the camera sees (plus margins); they
are sample bounds, not interval bounds (documented in docs/scene-format.md, *Formulas*).
The same samples refuse values out of range there (:func:`_check_values`). Oracle: the
same SymPy trees as NumPy operations.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Hashable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, cast

import numpy as np
from numpy.typing import NDArray

from glshade.components.base import SceneView, SurfaceComponent, UniformContext
from glshade.components.surface.freeform import (
    MARCH_GLSL,
    march_loop_iterations,
    march_uniforms,
)
from glshade.errors import SceneError
from glshade.params import Table, param

if TYPE_CHECKING:  # the grammar is loaded by the first formula parsed
    from glshade.components.camera.perspective.table import Camera
    from glshade.components.surface.formula.grammar import Formula as ParsedFormula

#: Samples per side of the grid the bounds are taken on, and their safety factor.
BOUND_SAMPLES = 129
BOUND_SAFETY = 1.5
#: The largest |f| (mm) and curvature bound (1/mm) over the region the camera sees: far
#: beyond any part, and small enough that the march's arithmetic cannot overflow (fp32).
MAX_HEIGHT_MM = 1e9
MAX_CURVATURE = 1e9


def check_formula(values: dict[str, Any]) -> None:
    """A formula surface's expression and parameters parse (the error names the token)."""
    if values.get("kind") == "formula":
        parsed(values["expression"], values.get("parameters") or ())


@dataclass(frozen=True)
class FormulaTable(Table):
    """The formula ``f(x, z)`` and its named parameters."""

    table = "surface"
    table_checks = (check_formula,)

    expression: str = param(
        "surface.expression", "mm", "0.0005*x^2 - 0.0002*z^2",
        "f(x, z) in mm, of x and z in mm and the parameters (a saddle by default; grammar: "
        "docs/scene-format.md, Formulas)",
        value_type="text", role="feature",
    )  # fmt: skip
    parameters: tuple[tuple[str, float], ...] = param(
        "surface.parameters", "", (),
        "named numbers the expression uses, e.g. { a = 0.002, b = 5.0 }",
        value_type="table",
    )  # fmt: skip


@functools.lru_cache(maxsize=64)
def parsed(expression: str, parameters: tuple[tuple[str, float], ...]) -> ParsedFormula:
    from glshade.components.surface.formula.grammar import parse_formula

    return parse_formula(expression, dict(parameters))


def formula_table(scene: SceneView) -> FormulaTable:
    """The scene's surface table, as the formula reads it."""
    return cast(FormulaTable, scene.surface)


def formula_of(scene: SceneView) -> ParsedFormula:
    surface = formula_table(scene)
    return parsed(surface.expression, surface.parameters)


class Formula(SurfaceComponent):
    name = "formula"
    rank = 3
    doc = "y = f(x, z) written as a formula of x and z (paper eq. 3)"
    table = FormulaTable

    def features(self, scene: SceneView) -> dict[str, Hashable]:
        from glshade.components.surface.formula.printers import GLSL_FUNCTIONS

        formula = formula_of(scene)
        return {
            "formula_functions": GLSL_FUNCTIONS,
            "formula_body": formula.glsl(scene.render.precision),
            "formula_parameters": tuple(name for name, _ in formula.parameters),
        }

    def glsl(self, variables: Mapping[str, Hashable]) -> tuple[str, ...]:
        return (*MARCH_GLSL, "formula.glsl")

    def loop_iterations(self, scene: SceneView, solver: Any) -> int:
        return march_loop_iterations(scene, solver)

    def uniforms(self, scene: SceneView, context: UniformContext) -> dict[str, object]:
        from glshade.components.surface.formula.functions import PARAMETER_PREFIX

        lo, hi, curvature = bounds(scene)
        values = {PARAMETER_PREFIX + name: value for name, value in formula_of(scene).parameters}
        return {
            **values,
            "u_surface_origin": tuple(float(v) for v in context.origin),
            "u_surface_lo": lo,
            "u_surface_hi": hi,
            "u_surface_curvature": curvature,
            **march_uniforms(scene, context),
        }

    def second_derivatives(self, scene: SceneView) -> tuple[float, float]:
        """``(f_zz, f_xx)`` at the origin, almost everywhere (0 on a kink); 0 where the
        formula has no finite value there."""
        fxx, _, fzz = (float(h(0.0, 0.0)) for h in formula_of(scene).hessian)
        fzz, fxx = (v if math.isfinite(v) else 0.0 for v in (fzz, fxx))
        return fzz, fxx

    def describe(self, scene: SceneView) -> str:
        text = formula_table(scene).expression
        return f"y = {text if len(text) <= 40 else text[:37] + '...'}"

    # ------------------------------------------------------------------ oracle
    def band_roots(
        self, scene: SceneView, o: np.ndarray, d: np.ndarray, shift: float
    ) -> list[np.ndarray]:
        lo, hi, _ = bounds(scene)
        with np.errstate(divide="ignore", invalid="ignore"):
            return [
                np.where(d[:, 1] != 0, (level + shift - o[:, 1]) / d[:, 1], np.nan)
                for level in (hi, lo)
            ]

    def height(self, scene: SceneView, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        return formula_of(scene).numpy[0](x, z)

    def outside(self, scene: SceneView, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        return ~np.isfinite(self.height(scene, x, z))

    def normal(
        self, scene: SceneView, x: np.ndarray, z: np.ndarray, dx: np.ndarray, dz: np.ndarray
    ) -> np.ndarray:
        _, fx, fz = formula_of(scene).numpy
        return np.stack(
            [-(fx(x, z) + dx), np.ones(np.broadcast(x, z).shape), -(fz(x, z) + dz)], axis=-1
        )


def bounds(scene: SceneView) -> tuple[float, float, float]:
    """``(lo, hi, K)``: ``f`` lies in ``[lo, hi]`` (mm) and ``|f''|`` along any horizontal
    unit direction is below ``K`` (1/mm) over the region the camera sees; a SceneError
    where the formula's values there are out of range (:func:`_check_values`)."""
    return _bounds(formula_of(scene), _seen_box(scene), scene.render.precision)


def _seen_box(scene: SceneView) -> tuple[float, float, float, float]:
    """``(x0, x1, z0, z1)`` (mm): where the image's border rays meet the plane y = 0, and
    the defect's centre, with a margin of 25 % and 2 mm."""
    return _box(scene.camera, scene.defect.x0, scene.defect.z0)


@functools.lru_cache(maxsize=64)
def _box(cam: Camera, x0: float, z0: float) -> tuple[float, float, float, float]:
    edge_rows = np.unique(np.linspace(0, cam.height - 1, 9).round().astype(int))
    edge_cols = np.unique(np.linspace(0, cam.width - 1, 9).round().astype(int))
    points = [np.array([x0, z0])]
    for rows, cols in ((edge_rows, [0, cam.width - 1]), ([0, cam.height - 1], edge_cols)):
        for r in rows:
            for c in cols:
                o, d = cam.pixel_rays(slice(int(r), int(r) + 1), slice(int(c), int(c) + 1))
                o, d = (
                    np.asarray(o, float).reshape(-1, 3)[0],
                    np.asarray(d, float).reshape(-1, 3)[0],
                )
                t = -o[1] / d[1] if d[1] < 0 else 1000.0 / np.linalg.norm(d)
                points.append((o + min(t, 1000.0) * d)[[0, 2]])
    xz = np.array(points)
    lo, hi = xz.min(axis=0), xz.max(axis=0)
    margin = 0.25 * (hi - lo) + 2.0
    return (
        float(lo[0] - margin[0]),
        float(hi[0] + margin[0]),
        float(lo[1] - margin[1]),
        float(hi[1] + margin[1]),
    )


@functools.lru_cache(maxsize=64)
def _bounds(
    formula: ParsedFormula, box: tuple[float, float, float, float], precision: str
) -> tuple[float, float, float]:
    x = np.linspace(box[0], box[1], BOUND_SAMPLES)
    z = np.linspace(box[2], box[3], BOUND_SAMPLES)
    xx, zz = np.meshgrid(x, z)
    f, fx, fz = values = tuple(function(xx, zz) for function in formula.numpy)
    _check_values(formula, (xx, zz), values, box, precision)
    finite = np.isfinite(f)
    fxx, fxz, fzz = (h(xx, zz) for h in formula.hessian)
    with np.errstate(all="ignore"):  # inf - inf where the formula is undefined: left out
        spectral = np.abs(0.5 * (fxx + fzz)) + np.hypot(0.5 * (fxx - fzz), fxz)  # |eigenvalue|
        jumps = _gradient_jumps(fx, fz, x[1] - x[0], z[1] - z[0])
    largest = max(_finite_max(spectral), _finite_max(jumps))
    curvature = largest * BOUND_SAFETY + 1e-12
    if curvature > MAX_CURVATURE:
        raise _value_error(
            f"a curvature bound of {curvature:.3g} /mm",
            box,
            f"|f''| of at most {MAX_CURVATURE:.0e} /mm",
        )
    cell = math.hypot(x[1] - x[0], z[1] - z[0])
    slack = curvature * cell * cell / 8.0 + 1e-9 + 1e-9 * float(np.nanmax(np.abs(f[finite])))
    return float(np.min(f[finite]) - slack), float(np.max(f[finite]) + slack), curvature


def _finite_max(values: np.ndarray) -> float:
    return float(np.max(np.where(np.isfinite(values), values, 0.0), initial=0.0))


def _gradient_jumps(fx: np.ndarray, fz: np.ndarray, dx: float, dz: float) -> np.ndarray:
    """The largest ``|f''|`` along a horizontal direction that the change of the exact
    gradient across each grid cell implies: a kink (``abs``, ``min``, ``max``), where the
    second derivative is 0 almost everywhere, turns its slope change into a curvature."""
    fxx = (fx[:-1, 1:] - fx[:-1, :-1]) / dx
    fzx = (fz[:-1, 1:] - fz[:-1, :-1]) / dx
    fxz = (fx[1:, :-1] - fx[:-1, :-1]) / dz
    fzz = (fz[1:, :-1] - fz[:-1, :-1]) / dz
    mixed = 0.5 * (fzx + fxz)
    return np.abs(0.5 * (fxx + fzz)) + np.hypot(0.5 * (fxx - fzz), mixed)


def _check_values(
    formula: ParsedFormula,
    grid: tuple[NDArray[np.float64], NDArray[np.float64]],
    values: tuple[NDArray[np.float64], ...],
    box: tuple[float, float, float, float],
    precision: str,
) -> None:
    """Refuse a formula with no finite value over the region the camera sees, an infinite
    one, one beyond :data:`MAX_HEIGHT_MM`, or, for fp32, one where a step of computing
    ``f``, ``f_x``, ``f_z`` overflows in single precision though float64 finds it finite
    (the samples: the bounds' grid ``(xx, zz)``, and ``(f, f_x, f_z)`` there in
    float64)."""
    from glshade.components.surface.formula.grammar import abbreviated

    xx, zz = grid
    f = values[0]
    finite = np.isfinite(f)
    if not finite.any():
        raise SceneError(
            "surface.expression", "a formula with finite values where the camera looks"
        )
    allowed = f"a formula finite (or undefined, NaN) and within ±{MAX_HEIGHT_MM:.0e} mm"
    for bad in (np.isinf(f), finite & (np.abs(f) > MAX_HEIGHT_MM)):
        if bad.any():
            where = np.unravel_index(np.argmax(bad), f.shape)
            raise _value_error(f"f = {f[where]:.3g} mm{_at(xx, zz, where)}", box, allowed)
    if precision == "fp64":
        return
    found = formula.single_precision_overflow(xx, zz)
    if found is not None:
        step, wide, bad = found
        where = np.unravel_index(np.argmax(bad), bad.shape)
        raise _value_error(
            f"{abbreviated(step, 40)} = {wide[where]:.3g}{_at(xx, zz, where)}, which "
            "overflows in single precision,",
            box,
            f"an fp32 render needs f, f_x, f_z and each step of their evaluation "
            f"within ±{float(np.finfo(np.float32).max):.3g}",
        )


def _at(xx: np.ndarray, zz: np.ndarray, where: tuple[np.intp, ...]) -> str:
    return f" at x = {xx[where]:.4g}, z = {zz[where]:.4g} mm"


def _value_error(what: str, box: tuple[float, float, float, float], allowed: str) -> SceneError:
    from glshade.components.surface.formula.grammar import FormulaError

    region = (
        f"over the region the camera sees (x {box[0]:.4g} to {box[1]:.4g} mm, "
        f"z {box[2]:.4g} to {box[3]:.4g} mm)"
    )
    return FormulaError("surface.expression", what, None, (), f"{allowed} {region}")


COMPONENTS = (Formula,)
