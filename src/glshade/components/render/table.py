"""The render table (``[render]`` of a scene file): how a frame is computed. Three slots
keep their parameters in it: the sampling (precision, rays per pixel), the reflection
model and the Fresnel factor, whose selectors are fields here; the parameters of the
reflection and Fresnel components join it when the scene composes its tables."""

from __future__ import annotations

from dataclasses import dataclass

from glshade.components.fresnel.table import FresnelChoice
from glshade.components.reflection.table import ReflectionChoice
from glshade.components.render.sampling.table import SamplingTable


@dataclass(frozen=True)
class RenderTable(FresnelChoice, ReflectionChoice, SamplingTable):
    """Precision and rays per pixel, and which reflection model and Fresnel factor."""

    table = "render"
