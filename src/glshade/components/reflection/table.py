"""The reflection slot's selector, a field of the render table."""

from __future__ import annotations

from dataclasses import dataclass

from glshade.params import Table, param


@dataclass(frozen=True)
class ReflectionChoice(Table):
    """Which reflection component shades the hits."""

    table = "render"

    reflection: str = param(
        "render.reflection", "", "mirror", "the reflection model: which reflection component",
        value_type="choice", role="feature", flag="--reflection",
    )  # fmt: skip
