"""The cylinder of signed radius R, its axis along z (in the plane of incidence) or x.

Table: :class:`CylinderTable` (the radius and the axis). GLSL: ``lib/quadric.glsl`` and
``cylinder.glsl`` (the axis is a feature: only its branch is compiled). Oracle: the sag
form across the axis, a slab domain.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping
from dataclasses import dataclass
from typing import cast

import numpy as np

from glshade.components.base import SceneView, UniformContext
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

    @staticmethod
    def surface_table(scene: SceneView) -> CylinderTable:
        """The scene's surface table, as the cylinder reads it (the radius and the axis)."""
        return cast(CylinderTable, scene.surface)

    def features(self, scene: SceneView) -> dict[str, Hashable]:
        return {"cylinder_axis": self.surface_table(scene).axis}

    def glsl(self, variables: Mapping[str, Hashable]) -> tuple[str, ...]:
        return ("lib/quadric.glsl", "cylinder.glsl")

    def uniforms(self, scene: SceneView, context: UniformContext) -> dict[str, object]:
        surface = self.surface_table(scene)
        across = context.origin[0] if surface.axis == "z" else context.origin[2]
        return {**self.uniform_radius(scene), "u_surface_axis_off": float(across)}

    def second_derivatives(self, scene: SceneView) -> tuple[float, float]:
        surface = self.surface_table(scene)
        r = surface.radius
        return (-1.0 / r, 0.0) if surface.axis == "x" else (0.0, -1.0 / r)

    def describe(self, scene: SceneView) -> str:
        surface = self.surface_table(scene)
        return f"cylinder R {surface.radius:g} mm axis {surface.axis}"

    # ------------------------------------------------------------------ oracle
    def rho(self, scene: SceneView, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        return np.abs(x) if self.surface_table(scene).axis == "z" else np.abs(z)

    def dims(self, scene: SceneView) -> list[int]:
        return [0, 1] if self.surface_table(scene).axis == "z" else [2, 1]

    def domain(
        self, scene: SceneView, o: np.ndarray, d: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        _, a = self.signed_radius(scene)
        k = 0 if self.surface_table(scene).axis == "z" else 2
        oc, dc = o[:, k], d[:, k]
        with np.errstate(divide="ignore", invalid="ignore"):
            ta, tb = (-a - oc) / dc, (a - oc) / dc
        t1, t2 = np.minimum(ta, tb), np.maximum(ta, tb)
        vertical = dc == 0.0
        inside = np.abs(oc) <= a
        return self.vertical_rays(t1, t2, vertical, inside)

    def normal(
        self, scene: SceneView, x: np.ndarray, z: np.ndarray, dx: np.ndarray, dz: np.ndarray
    ) -> np.ndarray:
        s, _ = self.signed_radius(scene)
        _, w = self.sag(scene, x, z)
        if self.surface_table(scene).axis == "z":
            return np.stack([s * x - w * dx, w, -w * dz], axis=-1)
        return np.stack([-w * dx, w, s * z - w * dz], axis=-1)


COMPONENTS = (Cylinder,)
