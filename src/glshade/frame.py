"""What a render produces: the camera image, the screen-coordinate (uv) map and the mask.

A field is ``None`` when the call did not ask for it (nothing was computed for it).

Supersampling convention (shared by the shader and the NumPy reference): with ``n`` rays
per pixel side the sub-pixel sample ``(a, b)`` sits at ``((b + 0.5)/n, (a + 0.5)/n)``
inside the pixel; ``image`` is the mean radiance over all ``n²`` samples (a miss counts
0), ``uv`` the mean over the samples that reach the emitter (NaN when none does), and
``mask`` is True where at least one sample reaches the emitter. A pixel's ``n²`` x (lens)
aperture samples may be traced over several draws (the driver's loop limit): the frame is
the same set of rays either way, and ``rays`` counts them.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeAlias

import numpy as np

#: Where ``camera.exposure = "auto"`` puts the brightest emitter point the scene shows: this
#: share of the recorded range (a tenth of headroom for a dent's highlight and the noise).
AUTO_EXPOSURE_LEVEL = 0.9


def exposure_gain(exposure: float | str, radiance: np.ndarray) -> float:
    """The factor from radiance (1 = the emitter's peak seen in a perfect mirror) to the
    recorded range (1 = full scale): ``exposure`` itself, or for ``"auto"``
    :data:`AUTO_EXPOSURE_LEVEL` over the brightest finite value of ``radiance`` (1 where
    nothing is lit)."""
    if exposure != "auto":
        return float(exposure)
    values = np.asarray(radiance)
    finite = values[np.isfinite(values)]
    peak = float(finite.max()) if finite.size else 0.0
    return AUTO_EXPOSURE_LEVEL / peak if peak > 0.0 else 1.0


#: "auto" exposure gains a renderer keeps, at most (one per defect-free geometry).
MAX_AUTO_GAINS = 64


def auto_exposure_gain(
    scene: Any, gains: dict[str, float], radiance_of: Callable[[Any], np.ndarray]
) -> float:
    """``scene``'s ``camera.exposure`` as a number. For ``"auto"``: :func:`exposure_gain`
    of the radiance ``radiance_of`` renders of the defect-free scene its emitter exposes
    by (:meth:`EmitterComponent.exposure_scene`: the stripes at phase 0, the fringe screen
    at its brightest level), kept in ``gains`` by that scene (at most
    :data:`MAX_AUTO_GAINS`), so the images with and without the dent, at every phase or
    frame, are taken alike."""
    if scene.camera.exposure != "auto":
        return float(scene.camera.exposure)
    normal = scene.active.emitter.exposure_scene(scene.without_defect())
    key = json.dumps(normal.to_dict(), sort_keys=True, default=str)
    gain = gains.get(key)
    if gain is None:
        gain = exposure_gain("auto", radiance_of(normal))
        if len(gains) >= MAX_AUTO_GAINS:
            gains.pop(next(iter(gains)))
        gains[key] = gain
    return gain


#: The outputs a render can be asked for.
OUTPUTS: tuple[str, ...] = ("image", "uv", "mask", "distance", "iterations", "rays", "frames")


@dataclass(frozen=True)
class Region:
    """A rectangle of an image's pixels: ``rows`` rows from ``row0`` (row 0 at the top)
    and ``cols`` columns from ``col0``; what a render or a pass over a frame stack may be
    limited to (its arrays then have the region's shape)."""

    row0: int
    col0: int
    rows: int
    cols: int

    @classmethod
    def of_mask(cls, mask: np.ndarray) -> Region | None:
        """The bounding box of ``mask``'s True pixels (None: none)."""
        rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
        if not len(rows):
            return None
        r0, c0 = int(rows[0]), int(cols[0])
        return cls(r0, c0, int(rows[-1]) + 1 - r0, int(cols[-1]) + 1 - c0)

    @property
    def rows_slice(self) -> slice:
        return slice(self.row0, self.row0 + self.rows)

    @property
    def cols_slice(self) -> slice:
        return slice(self.col0, self.col0 + self.cols)

    @property
    def slices(self) -> tuple[slice, slice]:
        """``(rows, columns)``: the region of a full image array."""
        return self.rows_slice, self.cols_slice

    @property
    def viewport(self) -> tuple[int, int, int, int]:
        """``(x, y, width, height)`` in GL's framebuffer coordinates (its row 0 is the
        image's row 0: glshade's camera draws the top row first)."""
        return self.col0, self.row0, self.cols, self.rows

    scissor = viewport

    def contains(self, other: Region) -> bool:
        """Is every pixel of ``other`` one of this region's?"""
        return (
            self.row0 <= other.row0
            and self.col0 <= other.col0
            and other.row0 + other.rows <= self.row0 + self.rows
            and other.col0 + other.cols <= self.col0 + self.cols
        )

    def grown(self, pixels: int, height: int, width: int) -> Region:
        """This region widened by ``pixels`` on every side, cut to an image of ``height``
        x ``width``."""
        r0, c0 = max(self.row0 - pixels, 0), max(self.col0 - pixels, 0)
        r1 = min(self.row0 + self.rows + pixels, height)
        c1 = min(self.col0 + self.cols + pixels, width)
        return Region(r0, c0, r1 - r0, c1 - c0)


@dataclass(frozen=True)
class Frame:
    """``image``: radiance in [0, 1], float32 (H, W); ``uv``: emitter coordinates in mm,
    (H, W, 2), NaN where the ray reaches no emitter point, float32 from fp32 shaders and
    float64 from fp64 ones (and the NumPy reference); ``mask``: bool (H, W), True where
    the ray reaches the emitter. Row 0 is the top of the image.

    Diagnostics, computed only when asked for: ``distance``, float32 (H, W), principal
    point to the surface hit along the ray (mm; NaN where the ray hits no surface; the
    mean over the samples that hit, when supersampled); ``iterations``, float32 (H, W),
    evaluations of the gap function by the dent's root solve (0 without a defect; the
    most any sample needed, when supersampled); ``rays``, float32 (H, W), camera rays
    traced and summed into the pixel, all draws together (``render.supersample``² x the
    camera's aperture samples when every one was; a ray the driver's loop limit cut short
    is not counted).

    ``frames``: float32 (F, H, W), a stack of emitter frames shaded from the same rays
    (the frames the render was asked for, in that order: a fringe sequence), each the
    radiance the pixel sees as ``image`` would be for that frame alone; never developed by
    a sensor (its caller records each frame with its own noise)."""

    image: np.ndarray | None = None
    uv: np.ndarray | None = None
    mask: np.ndarray | None = None
    distance: np.ndarray | None = None
    iterations: np.ndarray | None = None
    rays: np.ndarray | None = None
    frames: np.ndarray | None = None

    @property
    def shape(self) -> tuple[int, int]:
        for array in (self.image, self.uv, self.mask, self.distance, self.iterations, self.rays):
            if array is not None:
                return (int(array.shape[0]), int(array.shape[1]))
        if self.frames is not None:
            return (int(self.frames.shape[1]), int(self.frames.shape[2]))
        raise ValueError("empty frame")

    def output(self, name: str) -> np.ndarray:
        """The array of output ``name``; an error (a caller's bug) when it was not asked
        for."""
        array = getattr(self, name)
        if array is None:
            raise ValueError(
                f"this frame has no {name!r}: render it with outputs including {name!r}"
            )
        return array


#: What names a render's outputs: one name, or several.
Outputs: TypeAlias = "str | tuple[str, ...] | list[str] | frozenset[str]"


def normalize_outputs(
    outputs: Outputs,
) -> frozenset[str]:
    """Check and canonicalise a request such as ``("image", "uv")``."""
    from glshade.errors import GlshadeError

    wanted = frozenset([outputs] if isinstance(outputs, str) else outputs)
    unknown = wanted - set(OUTPUTS)
    if unknown or not wanted:
        raise GlshadeError(
            f"outputs: must be a non-empty subset of {', '.join(OUTPUTS)}, got {sorted(wanted)}"
        )
    return wanted
