"""A conductor's Fresnel reflectance, complex index ``n + ik`` (polished steel,
aluminium): the library's ``fresnel.glsl``; table
:class:`~glshade.components.fresnel.reflectance.ComplexIndexTable`."""

from __future__ import annotations

from glshade.components.fresnel.reflectance import ComplexIndexTable, Reflectance


class Conductor(Reflectance):
    name = "conductor"
    rank = 2
    doc = "a conductor's Fresnel reflectance, complex index n + ik (polished steel, aluminium)"
    table = ComplexIndexTable

    def extinction(self, scene):
        return scene.render.extinction


COMPONENTS = (Conductor,)
