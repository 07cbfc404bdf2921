"""No Fresnel factor: the reflected radiance is the emitter's (the paper's model)."""

from __future__ import annotations

from collections.abc import Hashable

import numpy as np

from glshade.components.base import FresnelComponent, SceneView


class NoFresnel(FresnelComponent):
    name = "none"
    rank = 0
    doc = "no Fresnel factor: the reflected radiance is the emitter's"

    def features(self, scene: SceneView) -> dict[str, Hashable]:
        return {"fresnel": False}

    def reflectance(self, scene: SceneView, cos_i: np.ndarray) -> np.ndarray:
        return np.ones(np.shape(cos_i))


COMPONENTS = (NoFresnel,)
