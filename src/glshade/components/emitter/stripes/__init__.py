"""The stripe emitter: Gaussian stripes along ``u``, spaced along ``v``, on a plane in the
mirror position of the camera (it moves with the camera's elevation and the rig's azimuth).

Table and pattern: :class:`~glshade.components.emitter.stripes.table.Emitter`. GLSL:
``lib/emitter_plane.glsl`` (the plane, shared with the other emitters: where a reflected
ray lands, how fast ``v`` moves), ``stripes.glsl`` (the radiance, and the stripes seen
through a Gaussian or GGX lobe) and ``diffuse.glsl`` (a Lambertian reflection of the
whole emitter), each only where the program needs it.
Oracle: :meth:`Stripes.coordinates` and the pattern's radiance.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping
from typing import Any, cast

import numpy as np

from glshade.components.base import EmitterComponent, SceneView, UniformContext, no_sequence
from glshade.components.emitter import plane
from glshade.components.emitter.stripes.table import Emitter
from glshade.errors import GlshadeError


class Stripes(EmitterComponent):
    name = "stripes"
    doc = "a plane of Gaussian stripes facing the origin, opposite the camera"
    table = Emitter

    def glsl(self, variables: Mapping[str, Hashable]) -> tuple[str, ...]:
        if "frames" in cast("tuple[str, ...]", variables["outputs"]):
            raise GlshadeError(no_sequence(self.name))
        if not variables["shading"]:
            return ("lib/emitter_plane.glsl",)
        return (
            "lib/emitter_plane.glsl",
            *(("lib/kernels.glsl",) if variables["filtered"] else ()),
            "stripes.glsl",
            *(("diffuse.glsl",) if variables["diffuse"] else ()),
        )

    def uniforms(self, scene: SceneView, context: UniformContext) -> dict[str, object]:
        em = scene.emitter
        values = plane.uniforms(scene, context)
        if context.variables["shading"]:
            values.update(
                u_emitter_period=em.period, u_emitter_sigma=em.sigma_mm, u_emitter_phase=em.phase_mm
            )
            if context.variables["diffuse"]:
                values["u_emitter_mean"] = em.mean_radiance()
        return values

    def loop_iterations(self, scene: SceneView, solver: Any) -> int:
        # once per ray: the diffuse polygon (at most 5 corners)
        return 6 if scene.active.features(scene).get("diffuse") else 0

    def pattern_loop_iterations(self, scene: SceneView, solver: Any) -> int:
        # per pattern shaded: the harmonics of the stripes seen through a GGX lobe (at most 64)
        variables = scene.active.features(scene)
        return 65 if variables.get("filtered") and variables.get("kernel") == "ggx" else 0

    def pattern(self, scene: SceneView) -> Emitter:
        return scene.emitter

    # ------------------------------------------------------------------ oracle
    def jacobian(
        self,
        scene: SceneView,
        points: np.ndarray,
        r: np.ndarray,
        a1: np.ndarray,
        a2: np.ndarray,
    ) -> np.ndarray:
        """The plane's (:func:`glshade.components.emitter.plane.jacobian`)."""
        return plane.jacobian(scene, points, r, a1, a2, self.cover_glass(scene))

    def coordinates(
        self, scene: SceneView, points: np.ndarray, directions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Where rays meet the emitter: :func:`glshade.components.emitter.plane.coordinates`."""
        return plane.coordinates(scene, points, directions)


COMPONENTS = (Stripes,)
