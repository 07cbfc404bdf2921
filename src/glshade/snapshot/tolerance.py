"""How far a snapshot may move before its test fails, in the units the optics speak.

- ``image``: a pixel's difference, as a fraction of the emitter's peak radiance (the
  stripes' crest is 1; a sensor's full scale is 1);
- ``image_pixels``: how many pixels may differ by more than ``image``;
- ``visibility_px``: the paper's numbers (the contour shift, its continuous limit, the
  rays' deflection, a sensor's noise floor), in pixels of the image;
- ``pmd_mm``: a phase-measuring station's numbers in mm (screen shifts, noise, decoding
  error, the fitted σ) on the screen or part;
- ``pmd_um``: its numbers in µm (the fitted depth ``pmd_depth_um``).

:data:`DEFAULT` holds for two runs on one renderer; :data:`ACROSS_RENDERERS` (fp32
shaders) and :data:`ACROSS_RENDERERS_FP64` are the smallest tolerances a comparison on
another renderer (another driver or GPU, another Mesa or LLVM, the NumPy float64 oracle)
uses. Both are measured (``docs/snapshot-testing.md``, "Why these defaults").
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from glshade.errors import GlshadeError

#: Each tolerance's unit, in the order messages list them.
UNITS: dict[str, str] = {
    "image": "of the emitter's peak",
    "image_pixels": "pixels",
    "visibility_px": "px",
    "pmd_mm": "mm",
    "pmd_um": "µm",
}

#: The most any tolerance may be: beyond it nothing would ever fail.
_LIMITS: dict[str, float] = {
    "image": 1.0,
    "image_pixels": float(1 << 31),
    "visibility_px": 1e6,
    "pmd_mm": 1e4,
    "pmd_um": 1e7,
}


@dataclass(frozen=True)
class Tolerances:
    """One comparison's tolerances (see the module's docstring for the units)."""

    image: float = 1e-3
    image_pixels: int = 0
    visibility_px: float = 0.01
    pmd_mm: float = 2e-4
    pmd_um: float = 2e-4

    def with_overrides(self, overrides: Mapping[str, Any], where: str) -> Tolerances:
        """These tolerances with some replaced; ``where`` names the overrides' origin in
        the one line an unknown name or a value out of range gets."""
        for name, value in overrides.items():
            _check(name, value, where)
        return dataclasses.replace(self, **dict(overrides))

    def at_least(self, floor: Tolerances) -> Tolerances:
        """Each tolerance no smaller than ``floor``'s."""
        return Tolerances(
            **{
                name: max(getattr(self, name), getattr(floor, name))
                for name in (f.name for f in dataclasses.fields(self))
            }
        )

    def describe(self) -> str:
        """``image 0.001 of the emitter's peak (0 pixels beyond), visibility 0.01 px, …``"""
        return (
            f"image {self.image:g} of the emitter's peak ({self.image_pixels} pixels beyond), "
            f"visibility {self.visibility_px:g} px, PMD {self.pmd_mm:g} mm and "
            f"{self.pmd_um:g} µm"
        )


def _check(name: str, value: Any, where: str) -> None:
    if name not in UNITS:
        raise GlshadeError(
            f"{where}: unknown tolerance {name!r}; the tolerances are " + ", ".join(UNITS)
        )
    integer = name == "image_pixels"
    kinds = (int,) if integer else (int, float)
    limit = _LIMITS[name]
    if (
        isinstance(value, bool)
        or not isinstance(value, kinds)
        or not math.isfinite(value)
        or not 0 <= value <= limit
    ):
        what = "a whole number" if integer else "a number"
        raise GlshadeError(
            f"{where}: {name} must be {what} from 0 to {limit:g} ({UNITS[name]}), got {value!r}"
        )


#: Two runs on one renderer: a pixel may move by a thousandth of the peak (five times the
#: largest difference measured between llvmpipe and an NVIDIA driver), none beyond; the
#: paper's numbers by 0.01 px (a hundred times the records' rounding); a station's in mm
#: by 2e-4 mm (twice the rounding of its fitted σ), its depth by 2e-4 µm (twice the
#: record's rounding of it): a dent 4 % deeper (5.2 µm for 5) moves the fitted depth by
#: 0.2 µm, a thousand times that.
DEFAULT = Tolerances()

#: The least tolerance between two renderers with fp32 shaders, or between fp32 and the
#: NumPy float64 oracle: measured (docs/snapshot-testing.md, "Why these defaults") at most
#: 1.7e-4 of the peak (llvmpipe against an NVIDIA H200 driver) and 1.1e-4 (against the
#: oracle), no pixel beyond 1e-3; the numbers within 1.2e-4 px, 4.9e-5 mm and 1.8e-5 µm
#: before the records round them (to 1e-4 px, 1e-4 mm and 1e-4 µm).
ACROSS_RENDERERS = Tolerances(
    image=2e-4, image_pixels=0, visibility_px=1e-3, pmd_mm=2e-4, pmd_um=2e-4
)
#: The same with fp64 shaders: images within 3e-7 of the peak (llvmpipe against NVIDIA,
#: and against the oracle); the numbers still differ by the records' rounding.
ACROSS_RENDERERS_FP64 = Tolerances(
    image=1e-6, image_pixels=0, visibility_px=1e-3, pmd_mm=2e-4, pmd_um=2e-4
)
