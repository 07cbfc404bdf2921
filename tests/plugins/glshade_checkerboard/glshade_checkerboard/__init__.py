"""A toy third-party glshade emitter whose pattern varies along both screen coordinates:
a checkerboard of square cells on the emitter's plane.

Installed as a package, it is found through its entry point (``pyproject.toml``)::

    [project.entry-points."glshade.components"]
    checkerboard = "glshade_checkerboard:Checkerboard"

and then fills the emitter slot as ``emitter.kind = "checkerboard"``, with its one
parameter ``emitter.cell``. It owns, like a built-in emitter: its table, its uniforms
(the plane's, from glshade's library, and ``u_emitter_cell``), its GLSL
(``lib/emitter_plane.glsl`` and ``checkerboard.glsl`` beside this module) and its NumPy
float64 oracle (where rays meet the plane, and the pattern there). The paper's stripe
metric cannot read it (it has no stripes); an instrument that reads images can
(``measured_by``: the brightness instrument of ``glshade_brightness``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from glshade.components.base import EmitterComponent, no_sequence
from glshade.components.emitter import plane
from glshade.errors import GlshadeError
from glshade.params import Table, param

__all__ = ["Checkerboard", "CheckerboardTable"]


@dataclass(frozen=True)
class CheckerboardTable(Table):
    """The checkerboard's cell."""

    table = "emitter"

    cell: float = param(
        "emitter.cell", "mm", 10.0, "checkerboard: the side of a square cell",
        lo=0.0, hi=1000.0, nonzero=True,
    )  # fmt: skip


class Checkerboard(EmitterComponent):
    name = "checkerboard"
    doc = "a checkerboard of square cells facing the origin (plug-in glshade-checkerboard)"
    table = CheckerboardTable
    measured_by = "brightness"

    def glsl(self, variables):
        if "frames" in variables["outputs"]:
            raise GlshadeError(no_sequence(self.name))
        if not variables["shading"]:
            return ("lib/emitter_plane.glsl",)
        if variables["filtered"] or variables["diffuse"]:
            raise GlshadeError(
                "emitter.kind = checkerboard: a mirror reflection only (render.reflection = "
                '"mirror")'
            )
        return ("lib/emitter_plane.glsl", "checkerboard.glsl")

    def uniforms(self, scene, context):
        values = plane.uniforms(scene, context)
        if context.variables["shading"]:
            values["u_emitter_cell"] = scene.emitter.cell
        return values

    def feature_mm(self, scene):
        return scene.emitter.cell

    # ------------------------------------------------------------------ oracle
    def coordinates(self, scene, points, directions):
        return plane.coordinates(scene, points, directions)

    def jacobian(self, scene, points, r, a1, a2):
        return plane.jacobian(scene, points, r, a1, a2)

    def radiance_uv(self, scene, u, v):
        """1 where the cell's row and column have the same parity, else 0."""
        cell = scene.emitter.cell
        columns, rows = np.floor(np.asarray(u) / cell), np.floor(np.asarray(v) / cell)
        return (np.mod(columns + rows, 2.0) < 0.5).astype(np.float64)
