"""How a frame is computed: the arithmetic precision and the rays per pixel.

Table: :class:`~glshade.components.render.sampling.table.SamplingTable`. GLSL:
``precision_fp32.glsl`` or ``precision_fp64.glsl`` (the program's preamble: it defines
``real``); the supersampling loop itself is the fragment template's.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping

from glshade.components.base import RenderComponent, SceneView, UniformContext
from glshade.components.render.sampling.table import SamplingTable


class Sampling(RenderComponent):
    name = "sampling"
    doc = "float32 or float64 arithmetic, one or n x n rays per pixel"
    table = SamplingTable

    def features(self, scene: SceneView) -> dict[str, Hashable]:
        return {"precision": scene.render.precision, "supersample": scene.render.supersample > 1}

    def glsl(self, variables: Mapping[str, Hashable]) -> tuple[str, ...]:
        return (f"precision_{variables['precision']}.glsl",)

    def uniforms(self, scene: SceneView, context: UniformContext) -> dict[str, object]:
        if not context.variables["supersample"]:
            return {}
        return {"u_render_supersample": scene.render.supersample}


COMPONENTS = (Sampling,)
