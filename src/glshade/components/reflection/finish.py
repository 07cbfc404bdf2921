"""The surface finish shared by every reflection model: the paper's eq. (1).

Beckmann and Spizzichino's roughness parameter ``g = (2π σ_h (cos θi + cos θr) / λ)²``
(``σ_h``: the rms height of the finish, ``λ``: the wavelength) sets the *coherent*
(specular) fraction of the reflected light, ``exp(-g)``. In the mirror direction
``θr = θi``, so ``g = (4π σ_h cos θi / λ)²``: it falls as the view grazes, and a finish
that scatters most light when seen from above is nearly a mirror seen from the side. The
paper prints ``4π`` in front of ``(cos θi + cos θr)``; Beckmann's own form (and every
text since) has ``2π``, which this module uses (the paper's factor amounts to a doubled
``σ_h``; ``docs/physics.md``).

The coherent part is the mirror reflection of the stripes. The incoherent remainder
``1 - exp(-g)`` goes where the reflection model puts scattered light: into its lobe
(Blinn-Phong, Beckmann, GGX), or, for the mirror, which has none, into a Lambertian
(diffuse) reflection of the emitter: ``(1/π) ∫ L cos θ dω`` over the part of the
emitter above the tangent plane, with the stripes' mean radiance ``σ √(2π) / P`` (the
diffuse kernel spans hundreds of mm of emitter: the stripes average out).

Table: :class:`FinishTable`, a base of every reflection model's table. GLSL: the library's
``coherence.glsl`` (and, for the mirror, the emitter's diffuse reflection).
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, cast

import numpy as np
from numpy.typing import NDArray

from glshade.params import Control, Table, param

if TYPE_CHECKING:
    from glshade.components.base import SceneView


@dataclass(frozen=True)
class FinishTable(Table):
    """The finish's roughness and the light's wavelength (paper eq. (1))."""

    table = "render"

    height_rms_um: float = param(
        "render.height_rms_um", "µm", 0.0,
        "paper eq. (1): rms height sigma_h of the finish; the coherent (mirror) fraction is "
        "exp(-(4 pi sigma_h cos(i) / lambda)^2), the rest is scattered into the model's lobe "
        "(the mirror's: Lambertian). 0: off",
        lo=0.0, closed=True, role="feature", flag="--height-rms",
        control=Control("height rms", 0.0, 0.2, fmt="%.3f um"), plausible_max=5.0,
        plausible_why="a finish this rough reflects no coherent light at any angle",
    )  # fmt: skip
    wavelength_um: float = param(
        "render.wavelength_um", "µm", 0.55, "paper eq. (1): wavelength lambda of the light",
        lo=0.0, flag="--wavelength", plausible_max=20.0,
        plausible_why="beyond the thermal infrared",
    )  # fmt: skip


def coherence_on(scene: SceneView) -> bool:
    return cast(FinishTable, scene.render).height_rms_um > 0.0


def coherence_uniforms(scene: SceneView) -> dict[str, object]:
    """``u_reflection_coherence``: ``4π σ_h / λ`` (dimensionless)."""
    render = cast(FinishTable, scene.render)
    ratio = render.height_rms_um / render.wavelength_um
    return {"u_reflection_coherence": 4.0 * math.pi * ratio}


def features(
    scene: SceneView, kernel: str = "none", filtered: bool = False, diffuse: bool = False
) -> dict[str, Hashable]:
    """The template variables every reflection component declares: ``coherence`` (eq. (1)
    is on), ``kernel`` (``none``, ``gaussian``, ``ggx``: the unit kernel of its lobe,
    ``shaders/lib/kernels.glsl``) and what it asks of the emitter's GLSL: ``filtered`` (the
    pattern seen through the lobe's footprint, ``emitter_filtered`` and
    ``emitter_jacobian``) and ``diffuse`` (a Lambertian reflection of the emitter)."""
    return {
        "coherence": coherence_on(scene),
        "kernel": kernel,
        "filtered": filtered,
        "diffuse": diffuse,
    }


def glsl(variables: Mapping[str, Hashable], *model_files: str) -> tuple[str, ...]:
    """A reflection model's files, after the library's ``coherence.glsl`` when eq. (1) is
    on and its lobe's ``kernels.glsl``; none in a program that shades no pattern."""
    if not variables["shading"]:
        return ()
    library = ("lib/kernels.glsl",) if variables["kernel"] != "none" else ()
    if variables["coherence"]:
        library = ("lib/coherence.glsl", *library)
    return (*library, *model_files)


def uniforms(scene: SceneView, variables: Mapping[str, Hashable]) -> dict[str, object]:
    """eq. (1)'s uniform where the program has it."""
    return coherence_uniforms(scene) if variables["shading"] and variables["coherence"] else {}


def coherent_fraction(scene: SceneView, cos_i: np.ndarray) -> np.ndarray:
    """``exp(-g)`` in the mirror direction, ``g = (4π σ_h cos θi / λ)²`` (float64)."""
    render = cast(FinishTable, scene.render)
    k = 4.0 * math.pi * render.height_rms_um / render.wavelength_um
    return np.exp(-((k * np.asarray(cos_i)) ** 2))


def lambert(scene: SceneView, p: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Lambertian radiance of the emitter at hits ``p`` (N, 3) with unit normals ``n``: the
    emitter component's oracle (:meth:`EmitterComponent.diffuse
    <glshade.components.base.EmitterComponent.diffuse>`)."""
    return scene.active.emitter.diffuse(scene, p, n)


def mirror_radiance(scene: SceneView, uv: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """The emitter's radiance where mirror rays land at screen points ``uv`` ((…, 2) mm; 0
    where not ``ok``)."""
    safe = np.where(ok[..., None], uv, 0.0)
    radiance = scene.active.emitter.radiance_uv(scene, safe[..., 0], safe[..., 1])
    return np.where(ok, radiance, 0.0)


def mix_coherent(
    scene: SceneView,
    mirror_value: NDArray[np.float64],
    lobe_value: NDArray[np.float64],
    d: NDArray[np.float64],
    n: NDArray[np.float64],
) -> NDArray[np.float64]:
    """``exp(-g) mirror + (1 - exp(-g)) lobe`` when eq. (1) is on, else the lobe value."""
    if not coherence_on(scene):
        return lobe_value
    c = coherent_fraction(scene, -np.einsum("nk,nk->n", d, n))
    return c * mirror_value + (1.0 - c) * lobe_value
