"""The sampling's parameters in the render table: precision and rays per pixel."""

from __future__ import annotations

from dataclasses import dataclass

from glshade.params import Control, Table, param

MAX_SUPERSAMPLE = 16
PRECISIONS: tuple[str, ...] = ("fp32", "fp64")


@dataclass(frozen=True)
class SamplingTable(Table):
    """Precision and rays per pixel."""

    table = "render"

    precision: str = param(
        "render.precision", "", "fp32",
        "arithmetic of the shader: fp32, or fp64 (the GPU-side reference)",
        value_type="choice", choices=PRECISIONS, role="feature", flag="--precision",
    )  # fmt: skip
    supersample: int = param(
        "render.supersample", "", 1,
        "rays per pixel side (n x n rays per pixel; 1 = one ray through the centre)",
        value_type="integer", lo=1, hi=MAX_SUPERSAMPLE, role="feature", flag="--supersample",
        control=Control("supersample", 1, 8, fmt="%d"),
    )  # fmt: skip
