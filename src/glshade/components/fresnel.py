"""Fresnel reflectance (the angular dependence the paper's ref. [16] points at).

The reflected radiance is multiplied by the unpolarised Fresnel reflectance
``R(θi) = (Rs + Rp) / 2`` of the incidence angle at the hit (``cos θi = -d·n``; for a
narrow lobe the half vector's angle is the same): of a **dielectric** (a clear coat,
index ``n``) or a **conductor** (complex index ``n + i k``: polished steel, aluminium).
Typical values at 550 nm: clear coat ``n = 1.5``; aluminium ``n = 0.96, k = 6.69``
(Rakić 1995); iron / polished steel ``n ≈ 2.9, k ≈ 3.0`` (Johnson & Christy 1974).

GLSL: ``fresnel.glsl``, the real-arithmetic form of the complex equations (pbrt's
``FrConductor``; a dielectric is ``k = 0``). Oracle: :meth:`FresnelComponent.reflectance`,
Snell's law and the amplitude coefficients in complex NumPy arithmetic.
"""

from __future__ import annotations

import numpy as np

from glshade.components.base import Component
from glshade.scene.params import Control, Param

IOR = Param(
    "render.ior",
    "",
    1.5,
    "Fresnel: refractive index n of the surface (clear coat 1.5; aluminium 0.96; steel 2.9)",
    lo=0.0,
    flag="--ior",
    control=Control("ior", 0.1, 5.0, fmt="%.2f"),
)
EXTINCTION = Param(
    "render.extinction",
    "",
    0.0,
    "Fresnel, conductor: extinction coefficient k of the complex index n + ik "
    "(aluminium 6.69; steel 3.0)",
    lo=0.0,
    closed=True,
    flag="--extinction",
    control=Control("extinction k", 0.0, 10.0, fmt="%.2f"),
)


class FresnelComponent(Component):
    """The Fresnel slot. Oracle: :meth:`reflectance`."""

    slot = "fresnel"

    def features(self, scene):
        return {"fresnel": True}

    def glsl(self, variables):
        return ("fresnel.glsl",) if "image" in variables["outputs"] else ()

    def uniforms(self, scene, frame):
        if "image" not in frame.variables["outputs"]:
            return {}
        return {"u_ior": scene.render.ior, "u_extinction": self.extinction(scene)}

    def image_from_v(self, scene):
        return False

    def keeps_emitter_scale(self, scene):
        return False

    def extinction(self, scene) -> float:
        return 0.0

    def reflectance(self, scene, cos_i: np.ndarray) -> np.ndarray:
        """Unpolarised reflectance at incidence ``cos θi`` from air (complex Snell's law)."""
        eta = complex(scene.render.ior, self.extinction(scene))
        c = np.clip(np.asarray(cos_i, np.float64), 0.0, 1.0).astype(complex)
        cos_t = np.sqrt(1.0 - (1.0 - c * c) / eta**2)
        cos_t = np.where((eta * cos_t).imag < 0, -cos_t, cos_t)  # the transmitted wave decays
        rs = (c - eta * cos_t) / (c + eta * cos_t)
        rp = (eta * c - cos_t) / (eta * c + cos_t)
        return 0.5 * (np.abs(rs) ** 2 + np.abs(rp) ** 2)


class NoFresnel(FresnelComponent):
    name = "none"
    doc = "no Fresnel factor: the reflected radiance is the emitter's"

    def features(self, scene):
        return {"fresnel": False}

    def glsl(self, variables):
        return ()

    def uniforms(self, scene, frame):
        return {}

    def image_from_v(self, scene):
        return True

    def keeps_emitter_scale(self, scene):
        return True

    def reflectance(self, scene, cos_i):
        return np.ones(np.shape(cos_i))


class Dielectric(FresnelComponent):
    name = "dielectric"
    doc = "a dielectric's Fresnel reflectance (a clear coat: n = 1.5)"
    params = (IOR,)


class Conductor(FresnelComponent):
    name = "conductor"
    doc = "a conductor's Fresnel reflectance, complex index n + ik (polished steel, aluminium)"
    params = (IOR, EXTINCTION)

    def extinction(self, scene):
        return scene.render.extinction
