"""A toy surface component, written the way a contributor adds one: this module (its
parameters as a table dataclass, its uniforms, its oracle) and one GLSL file
(``surface_tilted.glsl`` beside it, defining what ``shaders/slots/surface.glsl``
declares). The plane ``y = tan(tilt) z``."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from glshade.components.base import SurfaceComponent
from glshade.params import Control, Table, param


@dataclass(frozen=True)
class TiltedTable(Table):
    table = "surface"

    tilt_deg: float = param(
        "surface.tilt_deg", "deg", 0.0, "tilt of the plane about the x axis (toy)",
        lo=-30.0, hi=30.0, control=Control("tilt", -10.0, 10.0, fmt="%.2f deg"),
    )  # fmt: skip


class Tilted(SurfaceComponent):
    name = "tilted"
    doc = "the plane y = tan(tilt) z (a test plug-in)"
    table = TiltedTable
    glsl_dir = Path(__file__).parent

    def glsl(self, variables):
        return ("surface_tilted.glsl",)

    def uniforms(self, scene, context):
        return {"u_surface_slope": self._slope(scene), "u_surface_z0": float(context.origin[2])}

    @staticmethod
    def _slope(scene) -> float:
        return math.tan(math.radians(scene.surface.tilt_deg))

    def band_roots(self, scene, o, d, shift):
        s = self._slope(scene)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (shift - o[:, 1] + s * o[:, 2]) / (d[:, 1] - s * d[:, 2])
        return [np.where(np.isfinite(t), t, np.nan)]

    def height(self, scene, x, z):
        return self._slope(scene) * np.broadcast_to(z, np.broadcast(x, z).shape)

    def normal(self, scene, x, z, dx, dz):
        return np.stack([-dx, np.ones_like(dx), -(self._slope(scene) + dz)], axis=-1)
