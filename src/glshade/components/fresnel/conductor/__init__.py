"""A conductor's Fresnel reflectance, complex index ``n + ik`` (polished steel,
aluminium): the library's ``fresnel.glsl``; table
:class:`~glshade.components.fresnel.reflectance.ComplexIndexTable`."""

from __future__ import annotations

from typing import TYPE_CHECKING, cast

from glshade.components.fresnel.reflectance import ComplexIndexTable, Reflectance

if TYPE_CHECKING:
    from glshade.components.base import SceneView


class Conductor(Reflectance):
    name = "conductor"
    rank = 2
    doc = "a conductor's Fresnel reflectance, complex index n + ik (polished steel, aluminium)"
    table = ComplexIndexTable

    def extinction(self, scene: SceneView) -> float:
        return cast(ComplexIndexTable, scene.render).extinction


COMPONENTS = (Conductor,)
