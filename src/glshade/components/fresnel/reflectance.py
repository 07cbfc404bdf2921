"""Fresnel reflectance (the angular dependence the paper's ref. [16] points at).

The reflected radiance is multiplied by the unpolarised Fresnel reflectance
``R(θi) = (Rs + Rp) / 2`` of the incidence angle at the hit (``cos θi = -d·n``; for a
narrow lobe the half vector's angle is the same): of a **dielectric** (a clear coat,
index ``n``) or a **conductor** (complex index ``n + i k``: polished steel, aluminium).
Typical values at 550 nm: clear coat ``n = 1.5``; aluminium ``n = 0.96, k = 6.69``
(Rakić 1995); iron / polished steel ``n ≈ 2.9, k ≈ 3.0`` (Johnson & Christy 1974).

What the Fresnel components share: their tables (the refractive index; a conductor's
extinction too), the library's ``fresnel.glsl`` (the real-arithmetic form of the complex
equations, pbrt's ``FrConductor``; a dielectric is ``k = 0``) and the oracle,
:meth:`Reflectance.reflectance`: Snell's law and the amplitude coefficients in complex
NumPy arithmetic.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping
from dataclasses import dataclass
from typing import cast

import numpy as np

from glshade.components.base import FresnelComponent, SceneView, UniformContext
from glshade.params import Control, Table, param


@dataclass(frozen=True)
class IndexTable(Table):
    """The surface's refractive index."""

    table = "render"

    ior: float = param(
        "render.ior", "",  1.5,
        "Fresnel: refractive index n of the surface (clear coat 1.5; aluminium 0.96; steel 2.9)",
        lo=0.0, flag="--ior", control=Control("ior", 0.1, 5.0, fmt="%.2f"),
    )  # fmt: skip


@dataclass(frozen=True)
class ComplexIndexTable(IndexTable):
    """A conductor's complex index ``n + ik``."""

    extinction: float = param(
        "render.extinction", "", 0.0,
        "Fresnel, conductor: extinction coefficient k of the complex index n + ik "
        "(aluminium 6.69; steel 3.0)",
        lo=0.0, closed=True, flag="--extinction",
        control=Control("extinction k", 0.0, 10.0, fmt="%.2f"),
    )  # fmt: skip


class Reflectance(FresnelComponent):
    """A Fresnel factor of a (complex) refractive index. Oracle: :meth:`reflectance`."""

    def features(self, scene: SceneView) -> dict[str, Hashable]:
        return {"fresnel": True}

    def glsl(self, variables: Mapping[str, Hashable]) -> tuple[str, ...]:
        return ("lib/fresnel.glsl",) if variables["shading"] else ()

    def uniforms(self, scene: SceneView, context: UniformContext) -> dict[str, object]:
        if not context.variables["shading"]:
            return {}
        ior = cast(IndexTable, scene.render).ior
        return {"u_fresnel_ior": ior, "u_fresnel_extinction": self.extinction(scene)}

    def shades_from_emitter_map(self, scene: SceneView) -> bool:
        return False

    def keeps_emitter_scale(self, scene: SceneView) -> bool:
        return False

    def extinction(self, scene: SceneView) -> float:
        return 0.0

    def reflectance(self, scene: SceneView, cos_i: np.ndarray) -> np.ndarray:
        """Unpolarised reflectance at incidence ``cos θi`` from air (complex Snell's law)."""
        eta = complex(cast(IndexTable, scene.render).ior, self.extinction(scene))
        c = np.clip(np.asarray(cos_i, np.float64), 0.0, 1.0).astype(complex)
        cos_t = np.sqrt(1.0 - (1.0 - c * c) / eta**2)
        cos_t = np.where((eta * cos_t).imag < 0, -cos_t, cos_t)  # the transmitted wave decays
        rs = (c - eta * cos_t) / (c + eta * cos_t)
        rp = (eta * c - cos_t) / (eta * c + cos_t)
        return 0.5 * (np.abs(rs) ** 2 + np.abs(rp) ** 2)
