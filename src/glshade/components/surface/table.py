"""The surface table (``[surface]`` of a scene file): its selector, ``kind``; the surface
components' parameters join it when the scene composes its tables."""

from __future__ import annotations

from dataclasses import dataclass

from glshade.params import Table, param


@dataclass(frozen=True)
class SurfaceTable(Table):
    """The base surface ``y = f(x, z)``: ``kind`` names the surface component."""

    table = "surface"

    kind: str = param(
        "surface.kind", "", "flat", "the base surface: which surface component",
        value_type="choice", role="feature", flag="--surface",
    )  # fmt: skip
