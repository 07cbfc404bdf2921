"""The cylinder of signed radius R, its axis along z (in the plane of incidence) or x.

Table: :class:`CylinderTable` (the radius and the axis). GLSL: ``lib/quadric.glsl`` and
``cylinder.glsl`` (the axis is a feature: only its branch is compiled). Oracle: the sag
form across the axis, a slab domain.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from glshade.components.surface.quadric import Quadric, QuadricTable
from glshade.params import param


@dataclass(frozen=True)
class CylinderTable(QuadricTable):
    """The radius and the axis of a cylinder."""

    axis: str = param(
        "surface.axis", "", "z",
        "the cylinder's axis: z (in the plane of incidence) or x (across it)",
        value_type="choice", choices=("z", "x"), role="feature", flag="--axis",
    )  # fmt: skip


class Cylinder(Quadric):
    name = "cylinder"
    rank = 1
    doc = "y = sqrt(R² - a²) - R with a = x (axis z) or z (axis x)"
    table = CylinderTable

    def features(self, scene):
        return {"cylinder_axis": scene.surface.axis}

    def glsl(self, variables):
        return ("lib/quadric.glsl", "cylinder.glsl")

    def uniforms(self, scene, context):
        across = context.origin[0] if scene.surface.axis == "z" else context.origin[2]
        return {**self.uniform_radius(scene), "u_surface_axis_off": float(across)}

    def second_derivatives(self, scene):
        r = scene.surface.radius
        return (-1.0 / r, 0.0) if scene.surface.axis == "x" else (0.0, -1.0 / r)

    def describe(self, scene):
        return f"cylinder R {scene.surface.radius:g} mm axis {scene.surface.axis}"

    # ------------------------------------------------------------------ oracle
    def rho(self, scene, x, z):
        return np.abs(x) if scene.surface.axis == "z" else np.abs(z)

    def dims(self, scene):
        return [0, 1] if scene.surface.axis == "z" else [2, 1]

    def domain(self, scene, o, d):
        _, a = self.signed_radius(scene)
        k = 0 if scene.surface.axis == "z" else 2
        oc, dc = o[:, k], d[:, k]
        with np.errstate(divide="ignore", invalid="ignore"):
            ta, tb = (-a - oc) / dc, (a - oc) / dc
        t1, t2 = np.minimum(ta, tb), np.maximum(ta, tb)
        vertical = dc == 0.0
        inside = np.abs(oc) <= a
        return self.vertical_rays(t1, t2, vertical, inside)

    def normal(self, scene, x, z, dx, dz):
        s, _ = self.signed_radius(scene)
        _, w = self.sag(scene, x, z)
        if scene.surface.axis == "z":
            return np.stack([s * x - w * dx, w, -w * dz], axis=-1)
        return np.stack([-w * dx, w, s * z - w * dz], axis=-1)


COMPONENTS = (Cylinder,)
