"""How a frame is computed: the arithmetic precision and the rays per pixel.

GLSL: ``precision_fp32.glsl`` or ``precision_fp64.glsl`` (the program's preamble: it
defines ``real``); the supersampling loop itself is the fragment template's.
"""

from __future__ import annotations

from glshade.components.base import RenderComponent
from glshade.scene.params import Control, Param

MAX_SUPERSAMPLE = 16
PRECISIONS: tuple[str, ...] = ("fp32", "fp64")

PRECISION = Param(
    "render.precision",
    "",
    "fp32",
    "arithmetic of the shader: fp32, or fp64 (the GPU-side reference)",
    value_type="choice",
    choices=PRECISIONS,
    role="feature",
    flag="--precision",
)
SUPERSAMPLE = Param(
    "render.supersample",
    "",
    1,
    "rays per pixel side (n x n rays per pixel; 1 = one ray through the centre)",
    value_type="integer",
    lo=1,
    hi=MAX_SUPERSAMPLE,
    role="feature",
    flag="--supersample",
    control=Control("supersample", 1, 8, fmt="%d"),
)


class Sampling(RenderComponent):
    name = "sampling"
    doc = "float32 or float64 arithmetic, one or n x n rays per pixel"
    params = (PRECISION, SUPERSAMPLE)

    def features(self, scene):
        return {"precision": scene.render.precision, "supersample": scene.render.supersample > 1}

    def glsl(self, variables):
        return (f"precision_{variables['precision']}.glsl",)

    def uniforms(self, scene, frame):
        return {"u_supersample": scene.render.supersample} if frame.variables["supersample"] else {}
