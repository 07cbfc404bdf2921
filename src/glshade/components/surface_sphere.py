"""The sphere ``y = sqrt(R² - x² - z²) - R`` (R < 0: a concave bowl).

GLSL: ``quadric_crossing.glsl`` and ``surface_sphere.glsl``. Oracle: the sag form in
``rho = hypot(x, z)``, a disc domain.
"""

from __future__ import annotations

import numpy as np

from glshade.components.quadric import RADIUS, Quadric
from glshade.oracle.roots import circle_roots


class Sphere(Quadric):
    name = "sphere"
    doc = "y = sqrt(R² - x² - z²) - R"
    params = (RADIUS,)

    def glsl(self, variables):
        return ("quadric_crossing.glsl", "surface_sphere.glsl")

    def uniforms(self, scene, frame):
        return {
            **self.uniform_radius(scene),
            "u_axis_xz": (float(frame.origin[0]), float(frame.origin[2])),
        }

    def second_derivatives(self, scene):
        r = scene.surface.radius
        return -1.0 / r, -1.0 / r

    def describe(self, scene):
        return f"sphere R {scene.surface.radius:g} mm"

    # ------------------------------------------------------------------ oracle
    def rho(self, scene, x, z):
        return np.hypot(x, z)

    def dims(self, scene):
        return [0, 1, 2]

    def domain(self, scene, o, d):
        _, a = self.signed_radius(scene)
        dv = d[:, [0, 2]]
        t1, t2 = circle_roots(o[:, [0, 2]], dv, a)
        vertical = np.einsum("nk,nk->n", dv, dv) == 0.0
        inside = np.hypot(o[:, 0], o[:, 2]) <= a
        return self.vertical_rays(t1, t2, vertical, inside)

    def normal(self, scene, x, z, dx, dz):
        s, _ = self.signed_radius(scene)
        _, w = self.sag(scene, x, z)
        return np.stack([s * x - w * dx, w, s * z - w * dz], axis=-1)
