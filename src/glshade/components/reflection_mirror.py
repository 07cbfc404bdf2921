"""The ideal mirror: a pixel sees the emitter's radiance where its mirror ray lands.

GLSL: ``reflect_mirror.glsl``. Oracle: the stripe radiance at the mirror ray's ``v``.
"""

from __future__ import annotations

import numpy as np

from glshade.components.base import ReflectionComponent
from glshade.components.emitter_stripes import stripe_radiance


class Mirror(ReflectionComponent):
    name = "mirror"
    doc = "an ideal mirror"
    shades_from_v = True

    def glsl(self, variables):
        return ("reflect_mirror.glsl",) if "image" in variables["outputs"] else ()

    def shade(self, scene, p, d, n, v, ok):
        return np.where(ok, stripe_radiance(scene.emitter, np.where(ok, v, 0.0)), 0.0)
