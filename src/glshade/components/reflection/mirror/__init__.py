"""The ideal mirror: a pixel sees the emitter's radiance where its mirror ray lands.

With the paper's eq. (1) on (``render.height_rms_um > 0``), only the coherent fraction is
the mirror's; the rest is reflected diffusely (:mod:`glshade.components.reflection.finish`).

Table: :class:`~glshade.components.reflection.finish.FinishTable`. GLSL: ``mirror.glsl``
(+ the library's ``coherence.glsl`` and the emitter's diffuse reflection). Oracle: the
emitter's radiance at the mirror ray's ``v`` (and the finish's quadrature).
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping
from typing import Any

import numpy as np

from glshade.components.base import ReflectionComponent, SceneView, UniformContext
from glshade.components.reflection import finish


class Mirror(ReflectionComponent):
    name = "mirror"
    rank = 0
    doc = "an ideal mirror (with eq. (1): its coherent part, the rest Lambertian)"
    table = finish.FinishTable
    mirror_only = True

    def features(self, scene: SceneView) -> dict[str, Hashable]:
        return finish.features(scene, diffuse=finish.coherence_on(scene))

    def glsl(self, variables: Mapping[str, Hashable]) -> tuple[str, ...]:
        return finish.glsl(variables, "mirror.glsl")

    def uniforms(self, scene: SceneView, context: UniformContext) -> dict[str, object]:
        return finish.uniforms(scene, context.variables)

    def shades_from_emitter_map(self, scene: SceneView) -> bool:
        return not finish.coherence_on(scene)

    def loop_iterations(self, scene: SceneView, solver: Any) -> int:
        return 1  # the end of its loop over the patterns

    def pattern_loop_iterations(self, scene: SceneView, solver: Any) -> int:
        return 1  # each pattern once

    def keeps_emitter_scale(self, scene: SceneView) -> bool:
        return not finish.coherence_on(scene)

    def shade(
        self,
        scene: SceneView,
        p: np.ndarray,
        d: np.ndarray,
        n: np.ndarray,
        uv: np.ndarray,
        ok: np.ndarray,
    ) -> np.ndarray:
        mirror = finish.mirror_radiance(scene, uv, ok)
        if not finish.coherence_on(scene):
            return mirror
        return finish.mix_coherent(scene, mirror, finish.lambert(scene, p, n), d, n)


COMPONENTS = (Mirror,)
