"""No Fresnel factor: the reflected radiance is the emitter's (the paper's model)."""

from __future__ import annotations

import numpy as np

from glshade.components.base import FresnelComponent


class NoFresnel(FresnelComponent):
    name = "none"
    rank = 0
    doc = "no Fresnel factor: the reflected radiance is the emitter's"

    def features(self, scene):
        return {"fresnel": False}

    def reflectance(self, scene, cos_i):
        return np.ones(np.shape(cos_i))


COMPONENTS = (NoFresnel,)
