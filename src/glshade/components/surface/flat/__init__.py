"""The flat base surface ``y = 0``.

GLSL: ``flat.glsl``. Oracle: a plane (unbounded domain, one root per band).
"""

from __future__ import annotations

import numpy as np

from glshade.components.base import SurfaceComponent


class Flat(SurfaceComponent):
    name = "flat"
    rank = 0
    doc = "the plane y = 0"

    def glsl(self, variables):
        return ("flat.glsl",)

    def band_roots(self, scene, o, d, shift):
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (shift - o[:, 1]) / d[:, 1]
        return [np.where(np.isfinite(t), t, np.nan)]

    def height(self, scene, x, z):
        return np.zeros(np.broadcast(x, z).shape)

    def normal(self, scene, x, z, dx, dz):
        return np.stack([-dx, np.ones_like(dx), -dz], axis=-1)


COMPONENTS = (Flat,)
