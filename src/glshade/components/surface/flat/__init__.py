"""The flat base surface ``y = 0``.

GLSL: ``flat.glsl``. Oracle: a plane (unbounded domain, one root per band).
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping

import numpy as np

from glshade.components.base import SceneView, SurfaceComponent


class Flat(SurfaceComponent):
    name = "flat"
    rank = 0
    doc = "the plane y = 0"

    def glsl(self, variables: Mapping[str, Hashable]) -> tuple[str, ...]:
        return ("flat.glsl",)

    def band_roots(
        self, scene: SceneView, o: np.ndarray, d: np.ndarray, shift: float
    ) -> list[np.ndarray]:
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (shift - o[:, 1]) / d[:, 1]
        return [np.where(np.isfinite(t), t, np.nan)]

    def height(self, scene: SceneView, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        return np.zeros(np.broadcast(x, z).shape)

    def normal(
        self, scene: SceneView, x: np.ndarray, z: np.ndarray, dx: np.ndarray, dz: np.ndarray
    ) -> np.ndarray:
        return np.stack([-dx, np.ones_like(dx), -dz], axis=-1)


COMPONENTS = (Flat,)
