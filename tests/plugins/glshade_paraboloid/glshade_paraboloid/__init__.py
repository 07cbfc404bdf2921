"""A toy third-party glshade plug-in: the paraboloid of revolution
``y = -(x² + z²) / (2 R)`` about the gaze point (R > 0 a dome, R < 0 a bowl).

Installed as a package, it is found through its entry point (``pyproject.toml``)::

    [project.entry-points."glshade.components"]
    paraboloid = "glshade_paraboloid:Paraboloid"

and then fills the surface slot as ``surface.kind = "paraboloid"``, with its one
parameter ``surface.focal_radius``. It owns, like a built-in component: its table (the
parameter, declared with :func:`glshade.params.param`), its uniforms (``u_surface_...``),
its GLSL (``lib/quadric.glsl`` from glshade's library and ``paraboloid.glsl`` beside this
module, shipped as package data) and its NumPy float64 oracle.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from glshade.components.base import SurfaceComponent
from glshade.numerics import stable_roots
from glshade.params import Control, Table, param

__all__ = ["Paraboloid", "ParaboloidTable"]


@dataclass(frozen=True)
class ParaboloidTable(Table):
    """The paraboloid's radius of curvature at its apex."""

    table = "surface"

    focal_radius: float = param(
        "surface.focal_radius", "mm", 70.0,
        "paraboloid: radius of curvature at the apex, R in y = -(x² + z²) / (2 R); "
        "negative = concave (a bowl)",
        nonzero=True, flag="--focal-radius", allowed_text="non-zero (mm; negative = concave)",
        control=Control("focal radius", 5.0, 2000.0, log=True, fmt="%.1f mm", signed=True),
    )  # fmt: skip


class Paraboloid(SurfaceComponent):
    name = "paraboloid"
    rank = 100
    doc = "y = -(x² + z²) / (2 R) (plug-in glshade-paraboloid)"
    table = ParaboloidTable

    def glsl(self, variables):
        return ("lib/quadric.glsl", "paraboloid.glsl")

    def uniforms(self, scene, context):
        return {
            "u_surface_focal_radius": scene.surface.focal_radius,
            "u_surface_axis_xz": (float(context.origin[0]), float(context.origin[2])),
        }

    def second_derivatives(self, scene):
        r = scene.surface.focal_radius
        return -1.0 / r, -1.0 / r

    def describe(self, scene):
        return f"paraboloid R {scene.surface.focal_radius:g} mm"

    # ------------------------------------------------------------------ oracle (world mm)
    def band_roots(self, scene, o, d, shift):
        """Roots of ``y - f = shift``: ``a t² + 2 b t + c = 0`` with ``a = |d_xz|²``,
        ``b = o_xz·d_xz + R d_y``, ``c = |o_xz|² + 2 R (o_y - shift)``. The discriminant
        is formed as ``R² d_y² + 2 R (d_y o_xz·d_xz - h a) - (o_xz × d_xz)²``, which
        leaves out the cancellation of ``(o·d)² - |o|²|d|²``; a vertical ray
        (``a = 0``) has the one root ``-c / (2 b)``."""
        r = scene.surface.focal_radius
        q, dv = o[:, [0, 2]], d[:, [0, 2]]
        h = o[:, 1] - shift
        qa = np.einsum("nk,nk->n", dv, dv)
        qd = np.einsum("nk,nk->n", q, dv)
        qb = qd + r * d[:, 1]
        qc = np.einsum("nk,nk->n", q, q) + 2.0 * r * h
        cross = q[:, 0] * dv[:, 1] - q[:, 1] * dv[:, 0]
        disc = r * r * d[:, 1] ** 2 + 2.0 * r * (d[:, 1] * qd - h * qa) - cross * cross
        with np.errstate(invalid="ignore", divide="ignore"):
            sqrt_disc = np.where(disc >= 0.0, np.sqrt(np.maximum(disc, 0.0)), np.nan)
            t1, t2 = stable_roots(qa, qb, qc, sqrt_disc)
            vertical = qa == 0.0
            linear = np.where(vertical & (qb != 0.0), -0.5 * qc / qb, np.nan)
        return [np.where(vertical, linear, t1), np.where(vertical, np.nan, t2)]

    def height(self, scene, x, z):
        return -(x * x + z * z) / (2.0 * scene.surface.focal_radius)

    def normal(self, scene, x, z, dx, dz):
        r = scene.surface.focal_radius
        x, z, dx, dz = np.broadcast_arrays(x, z, dx, dz)
        return np.stack([x / r - dx, np.ones_like(dx, dtype=np.float64), z / r - dz], axis=-1)
