"""The Fresnel slot's selector, a field of the render table."""

from __future__ import annotations

from dataclasses import dataclass

from glshade.params import Table, param


@dataclass(frozen=True)
class FresnelChoice(Table):
    """Which Fresnel component weighs the reflected radiance."""

    table = "render"

    fresnel: str = param(
        "render.fresnel", "", "none", "the Fresnel reflectance: which Fresnel component",
        value_type="choice", role="feature", flag="--fresnel",
    )  # fmt: skip
