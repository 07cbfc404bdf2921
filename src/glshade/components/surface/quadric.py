"""What the curved base surfaces (cylinder, sphere) share: the signed radius (a table
both declare), the GLSL that picks the first crossing of a quadric (``lib/quadric.glsl``)
and the sag-form oracle.

A curved surface is ``y = f(rho)`` with ``rho`` the distance from its axis in the ``xz``
plane (the sphere: ``hypot(x, z)``; a cylinder: ``|x|`` or ``|z|``). ``f`` is evaluated
in the sag form ``-s rho² / (|R| + w)``, ``w = sqrt((|R| - rho)(|R| + rho))``, which
loses no digits near the apex or the rim.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

import numpy as np

from glshade.components.base import SceneView, SurfaceComponent
from glshade.numerics import circle_roots
from glshade.params import Control, Table, param


@dataclass(frozen=True)
class QuadricTable(Table):
    """The radius of a curved base surface."""

    table = "surface"

    radius: float = param(
        "surface.radius", "mm", 70.0, "radius of the cylinder or sphere; negative = concave",
        nonzero=True, flag="--radius", allowed_text="non-zero (mm; negative = concave)",
        control=Control("radius", 5.0, 2000.0, log=True, fmt="%.1f mm", signed=True),
    )  # fmt: skip


class Quadric(SurfaceComponent):
    """Base of the curved kinds: a subclass says which coordinates span its cross-section
    (``dims``, indices into (x, y, z), y included) and how far a point is from its axis."""

    def rho(self, scene: SceneView, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def dims(self, scene: SceneView) -> list[int]:
        raise NotImplementedError

    @staticmethod
    def surface_table(scene: SceneView) -> QuadricTable:
        """The scene's surface table, as the curved kinds read it."""
        return cast(QuadricTable, scene.surface)

    @staticmethod
    def signed_radius(scene: SceneView) -> tuple[float, float]:
        """``(s, a)``: ``s = sign(R)`` (+1 convex, -1 concave), ``a = |R|`` (mm)."""
        radius = Quadric.surface_table(scene).radius
        return (1.0 if radius > 0 else -1.0), abs(radius)

    def sag(self, scene: SceneView, x: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Base height ``f`` (mm) and ``w = sqrt(R² - rho²)`` with ``rho`` clipped to ``|R|``."""
        s, a = self.signed_radius(scene)
        rho = np.minimum(self.rho(scene, x, z), a)
        w = np.sqrt((a - rho) * (a + rho))
        return -s * rho * rho / (a + w), w

    def height(self, scene: SceneView, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        return self.sag(scene, x, z)[0]

    def outside(self, scene: SceneView, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        return self.rho(scene, x, z) > abs(self.surface_table(scene).radius)

    def band_roots(
        self, scene: SceneView, o: np.ndarray, d: np.ndarray, shift: float
    ) -> list[np.ndarray]:
        s, a = self.signed_radius(scene)
        y_centre = shift - s * a  # centre of the shifted sphere / circle
        oc = o - np.array([0.0, y_centre, 0.0])
        dims = self.dims(scene)
        return list(circle_roots(oc[:, dims], d[:, dims], a))

    @staticmethod
    def vertical_rays(
        t1: np.ndarray, t2: np.ndarray, vertical: np.ndarray, inside: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Rays that do not move across the domain: all of it (inside) or none of it."""
        t1 = np.where(vertical, np.where(inside, -np.inf, np.nan), t1)
        t2 = np.where(vertical, np.where(inside, np.inf, np.nan), t2)
        return t1, t2

    def uniform_radius(self, scene: SceneView) -> dict[str, object]:
        return {"u_surface_radius": self.surface_table(scene).radius}
