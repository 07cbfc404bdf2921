"""The ideal mirror: a pixel sees the emitter's radiance where its mirror ray lands.

With the paper's eq. (1) on (``render.height_rms_um > 0``), only the coherent fraction is
the mirror's; the rest is reflected diffusely (:mod:`glshade.components.finish`).

GLSL: ``reflect_mirror.glsl`` (+ ``reflect_coherence.glsl``, ``reflect_lambert.glsl``).
Oracle: the stripe radiance at the mirror ray's ``v`` (and the finish's quadrature).
"""

from __future__ import annotations

import numpy as np

from glshade.components import finish
from glshade.components.base import ReflectionComponent
from glshade.components.emitter_stripes import stripe_radiance


class Mirror(ReflectionComponent):
    name = "mirror"
    doc = "an ideal mirror (with eq. (1): its coherent part, the rest Lambertian)"
    params = finish.COHERENCE_PARAMS
    shades_from_v = True

    def features(self, scene):
        return finish.features(scene)

    def glsl(self, variables):
        lambert = ("reflect_lambert.glsl",) if variables["coherence"] else ()
        return finish.glsl(variables, *lambert, "reflect_mirror.glsl")

    def uniforms(self, scene, frame):
        values = finish.uniforms(scene, frame.variables)
        return {**values, "u_em_mean": finish.mean_radiance(scene.emitter)} if values else {}

    def image_from_v(self, scene):
        return not finish.coherence_on(scene)

    def keeps_emitter_scale(self, scene):
        return not finish.coherence_on(scene)

    def shade(self, scene, p, d, n, v, ok):
        mirror = np.where(ok, stripe_radiance(scene.emitter, np.where(ok, v, 0.0)), 0.0)
        if not finish.coherence_on(scene):
            return mirror
        return finish.mix_coherent(scene, mirror, finish.lambert(scene, p, n), d, n)
