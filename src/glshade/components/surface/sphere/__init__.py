"""The sphere ``y = sqrt(R² - x² - z²) - R`` (R < 0: a concave bowl).

Table: :class:`~glshade.components.surface.quadric.QuadricTable` (the radius). GLSL:
``lib/quadric.glsl`` and ``sphere.glsl``. Oracle: the sag form in
``rho = hypot(x, z)``, a disc domain.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping

import numpy as np

from glshade.components.base import SceneView, UniformContext
from glshade.components.surface.quadric import Quadric, QuadricTable
from glshade.numerics import circle_roots


class Sphere(Quadric):
    name = "sphere"
    rank = 2
    doc = "y = sqrt(R² - x² - z²) - R"
    table = QuadricTable

    def glsl(self, variables: Mapping[str, Hashable]) -> tuple[str, ...]:
        return ("lib/quadric.glsl", "sphere.glsl")

    def uniforms(self, scene: SceneView, context: UniformContext) -> dict[str, object]:
        axis = (float(context.origin[0]), float(context.origin[2]))
        return {**self.uniform_radius(scene), "u_surface_axis_xz": axis}

    def second_derivatives(self, scene: SceneView) -> tuple[float, float]:
        r = self.surface_table(scene).radius
        return -1.0 / r, -1.0 / r

    def describe(self, scene: SceneView) -> str:
        return f"sphere R {self.surface_table(scene).radius:g} mm"

    # ------------------------------------------------------------------ oracle
    def rho(self, scene: SceneView, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        return np.hypot(x, z)

    def dims(self, scene: SceneView) -> list[int]:
        return [0, 1, 2]

    def domain(
        self, scene: SceneView, o: np.ndarray, d: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        _, a = self.signed_radius(scene)
        dv = d[:, [0, 2]]
        t1, t2 = circle_roots(o[:, [0, 2]], dv, a)
        vertical = np.einsum("nk,nk->n", dv, dv) == 0.0
        inside = np.hypot(o[:, 0], o[:, 2]) <= a
        return self.vertical_rays(t1, t2, vertical, inside)

    def normal(
        self, scene: SceneView, x: np.ndarray, z: np.ndarray, dx: np.ndarray, dz: np.ndarray
    ) -> np.ndarray:
        s, _ = self.signed_radius(scene)
        _, w = self.sag(scene, x, z)
        return np.stack([s * x - w * dx, w, s * z - w * dz], axis=-1)


COMPONENTS = (Sphere,)
