"""A dielectric's Fresnel reflectance (a clear coat: n = 1.5): the library's
``fresnel.glsl`` with ``k = 0``; table
:class:`~glshade.components.fresnel.reflectance.IndexTable`."""

from __future__ import annotations

from glshade.components.fresnel.reflectance import IndexTable, Reflectance


class Dielectric(Reflectance):
    name = "dielectric"
    rank = 1
    doc = "a dielectric's Fresnel reflectance (a clear coat: n = 1.5)"
    table = IndexTable


COMPONENTS = (Dielectric,)
