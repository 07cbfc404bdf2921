"""Microfacet reflection: Beckmann and GGX lobes of roughness ``α``.

Cook–Torrance with height-correlated Smith shadowing ``G2 = 1 / (1 + Λ(wo) + Λ(l))``.
Over the half vector's slopes ``(x, y)`` (``h = normalise(n + x e1 + y e2)``, ``e1`` in
the plane of incidence) the pixel is ``∫ L(v(l)) P22(x, y) W dx dy`` with
``l = 2 (wo·h) h - wo`` and ``W = G2 (wo·h) / ((n·wo)(n·h))``; ``P22`` is the slope
density: ``exp(-r²/α²) / (π α²)`` (Beckmann), ``1 / (π α² (1 + r²/α²)²)`` (GGX). As
``α → 0`` both tend to the mirror. Fresnel is a separate slot (``render.fresnel``).

Three ways to integrate the stripes over the lobe (``render.lobe_method``):

- ``closed``: ``v`` linearised about the mirror ray; the lobe spreads ``v`` by the slope
  density's marginal, a Gaussian (Beckmann: the stripes stay Gaussian, wider) or
  ``α² / (2 (α² + s²)^{3/2})`` (GGX: each Fourier harmonic of the stripes is damped by
  ``β ω K1(β ω)``); shadowing at the mirror direction. One evaluation per ray.
- ``lattice``: ``render.lobe_samples`` slopes importance-sampled on a Fibonacci lattice
  (deterministic quasi-Monte Carlo), the exact integrand at each.
- ``sampling``: the same lattice shifted per pixel (randomised QMC: unbiased, noisy).

The default is the one on the error-versus-time front (``docs/accuracy.md``).

Table: :class:`MicrofacetTable`. GLSL: ``microfacet.glsl`` (the closed forms ask the
emitter for its pattern seen through a Gaussian or a GGX lobe). Oracle:
:meth:`Microfacet.shade`, Monte-Carlo
importance sampling (NumPy, fixed seed) with the BRDF written out (``D``, ``G``, the
sampling density), its standard error :attr:`Microfacet.oracle_samples` bounded.
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, cast

import numpy as np
from numpy.typing import NDArray

from glshade.components.base import ReflectionComponent, SceneView, UniformContext
from glshade.components.reflection import finish
from glshade.components.reflection.kernels import lobe_frame
from glshade.params import Control, param

if TYPE_CHECKING:  # the knob is imported when asked for
    from glshade.components.reflection.microfacet.accuracy import MicrofacetKnob

LOBE_METHODS = ("closed", "lattice", "sampling")
MAX_LOBE_SAMPLES = 4096


@dataclass(frozen=True)
class MicrofacetTable(finish.FinishTable):
    """A microfacet lobe's roughness and how it is integrated (and the finish of eq. (1))."""

    roughness: float = param(
        "render.roughness", "", 0.0,
        "microfacet roughness alpha (Beckmann: rms slope x sqrt 2; the reflected direction "
        "spreads by about 2 alpha rad); 0 is the mirror",
        lo=0.0, closed=True, flag="--roughness",
        control=Control("roughness", 1e-5, 0.05, log=True, fmt="%.2g"), plausible_max=0.5,
        plausible_why="a lobe this wide shows no stripes at any distance",
    )  # fmt: skip
    lobe_method: str = param(
        "render.lobe_method", "", "closed",
        "how the stripes are integrated over a microfacet lobe: closed (linearised, one "
        "evaluation), lattice (quasi-Monte Carlo, lobe_samples rays), sampling (the lattice "
        "randomised per pixel)",
        value_type="choice", choices=LOBE_METHODS, role="feature", flag="--lobe-method",
    )  # fmt: skip
    lobe_samples: int = param(
        "render.lobe_samples", "", 64, "microfacet lattice or sampling: slope samples per ray",
        value_type="integer", lo=1, hi=MAX_LOBE_SAMPLES, flag="--lobe-samples",
    )  # fmt: skip


def smith_lambda(kind: str, alpha: float, cos_t: np.ndarray) -> np.ndarray:
    """Smith's ``Λ`` of a direction at ``cos θ`` to the normal (Beckmann: Walter et al.'s
    rational fit, as the shader)."""
    c2 = np.maximum(np.asarray(cos_t, np.float64) ** 2, 1e-300)
    tan = np.sqrt(np.maximum(1.0 - c2, 0.0) / c2)
    if kind == "ggx":
        return 0.5 * (np.sqrt(1.0 + (alpha * tan) ** 2) - 1.0)
    with np.errstate(divide="ignore"):
        a = 1.0 / np.maximum(alpha * tan, 1e-300)
    return np.where(a >= 1.6, 0.0, (1.0 - 1.259 * a + 0.396 * a * a) / (3.535 * a + 2.181 * a * a))


def slope_density(kind: str, alpha: float, r2: np.ndarray) -> np.ndarray:
    """``P22`` at squared slope ``r²``."""
    if kind == "ggx":
        return 1.0 / (math.pi * alpha**2 * (1.0 + r2 / alpha**2) ** 2)
    return np.exp(-r2 / alpha**2) / (math.pi * alpha**2)


def sample_slopes(
    kind: str, alpha: float, u1: np.ndarray, u2: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Slopes ``(x, y)`` distributed as ``P22`` from uniforms (inverse CDF of the radius)."""
    if kind == "ggx":
        radius = alpha * np.sqrt(u1 / (1.0 - u1))
    else:
        radius = alpha * np.sqrt(-np.log1p(-u1))
    return radius * np.cos(2.0 * math.pi * u2), radius * np.sin(2.0 * math.pi * u2)


class Microfacet(ReflectionComponent):
    """Shared by :class:`Beckmann` and :class:`GGX`."""

    table = MicrofacetTable
    #: Monte-Carlo samples per pixel of the NumPy oracle (standard error ~ 1/sqrt of it).
    oracle_samples = 1 << 14

    #: The lobe's unit kernel (``shaders/lib/kernels.glsl``): its slopes' law at unit scale.
    kernel: str = "none"

    def features(self, scene: SceneView) -> dict[str, Hashable]:
        render = cast(MicrofacetTable, scene.render)
        closed = render.lobe_method == "closed"
        return {
            **finish.features(scene, kernel=self.kernel, filtered=closed),
            "lobe": self.name,
            "lobe_method": render.lobe_method,
        }

    def glsl(self, variables: Mapping[str, Hashable]) -> tuple[str, ...]:
        return finish.glsl(variables, "microfacet.glsl")

    def uniforms(self, scene: SceneView, context: UniformContext) -> dict[str, object]:
        if not context.variables["shading"]:
            return {}
        render = cast(MicrofacetTable, scene.render)
        values = finish.uniforms(scene, context.variables)
        values["u_reflection_alpha"] = render.roughness
        if context.variables["lobe_method"] != "closed":
            values["u_reflection_lobe_samples"] = render.lobe_samples
        return values

    def keeps_emitter_scale(self, scene: SceneView) -> bool:
        return False

    def work_factor(self, scene: SceneView) -> int:
        render = cast(MicrofacetTable, scene.render)
        return 1 if render.lobe_method == "closed" else render.lobe_samples

    def loop_iterations(self, scene: SceneView, solver: Any) -> int:
        # the lattice's loop over its slope samples, and the end of each loop over the
        # patterns (one per sample, one for eq. (1)'s coherent part or the closed form's)
        render = cast(MicrofacetTable, scene.render)
        if render.lobe_method == "closed":
            return 1
        return 2 * render.lobe_samples + 2

    def pattern_loop_iterations(self, scene: SceneView, solver: Any) -> int:
        # every pattern once per slope sample (the closed form: once)
        render = cast(MicrofacetTable, scene.render)
        return 1 if render.lobe_method == "closed" else render.lobe_samples + 1

    def accuracy_knob(self) -> MicrofacetKnob:
        # imported here: the knob is only run by `glshade accuracy`
        from glshade.components.reflection.microfacet.accuracy import MicrofacetKnob

        return MicrofacetKnob()

    def footprint(
        self, scene: SceneView, p: np.ndarray, d: np.ndarray, n: np.ndarray
    ) -> tuple[np.ndarray, str] | None:
        """``J (dl/dx, dl/dy) s``: the slopes' unit kernel at scale ``s`` (``α/√2`` for
        Beckmann's Gaussian slopes, ``α`` for GGX) mapped onto the emitter through the
        reflected direction's derivatives and the emitter's Jacobian ``J``; None for the
        mirror (``α = 0``)."""
        alpha = cast(MicrofacetTable, scene.render).roughness
        if alpha == 0.0:
            return None
        wo = -d
        cos_o = np.einsum("nk,nk->n", wo, n)
        e1, e2 = lobe_frame(n, wo)
        dl_x = 2.0 * np.einsum("nk,nk->n", wo, e1)[:, None] * n + 2.0 * cos_o[:, None] * e1
        dl_y = 2.0 * cos_o[:, None] * e2
        r = d - 2.0 * np.einsum("nk,nk->n", d, n)[:, None] * n
        scale = alpha * (math.sqrt(0.5) if self.kernel == "gaussian" else 1.0)
        emitter = scene.active.emitter
        return emitter.jacobian(scene, p, r, scale * dl_x, scale * dl_y), self.kernel

    def finish_name(self, scene: SceneView) -> str:
        return f"{self.name}, roughness {cast(MicrofacetTable, scene.render).roughness:.3g}"

    def lobe_std_rad(self, scene: SceneView) -> float | None:
        """The reflected direction turns by twice the facet's tilt: std ``2 α/√2``
        (Beckmann); GGX's heavy tails are summarised by the same scale."""
        render = cast(MicrofacetTable, scene.render)
        return math.sqrt(2.0) * render.roughness if render.roughness > 0 else None

    def sharpen_hint(self, scene: SceneView, ratio: float) -> str:
        return f"render.roughness <= {cast(MicrofacetTable, scene.render).roughness / ratio:.3g}"

    # ---------------------------------------------------------------- oracle
    def shade(
        self,
        scene: SceneView,
        p: np.ndarray,
        d: np.ndarray,
        n: np.ndarray,
        uv: np.ndarray,
        ok: np.ndarray,
        samples: int | None = None,
        seed: int = 0,
    ) -> np.ndarray:
        """Monte-Carlo estimate (``samples`` per pixel, fixed ``seed``) of the lobe
        integral: slopes drawn from ``P22``, so ``l`` has the density
        ``pdf(l) = D(h) (n·h) / (4 (wo·h))`` with ``D = P22 / (n·h)⁴``; each sample weighs
        ``f cos θl / pdf(l)``, ``f = D G2 / (4 cos θo cos θl)``. With eq. (1) on, the
        coherent fraction is the mirror's."""
        mirror = finish.mirror_radiance(scene, uv, ok)
        alpha = cast(MicrofacetTable, scene.render).roughness
        if alpha == 0.0:
            lobe = mirror
        else:
            lobe = self.monte_carlo(scene, p, d, n, samples or self.oracle_samples, seed)[0]
        return finish.mix_coherent(scene, mirror, lobe, d, n)

    def monte_carlo(
        self,
        scene: SceneView,
        p: NDArray[np.float64],
        d: NDArray[np.float64],
        n: NDArray[np.float64],
        samples: int,
        seed: int,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(mean, standard error)`` per hit."""
        alpha, kind = cast(MicrofacetTable, scene.render).roughness, self.name
        rng = np.random.default_rng(seed)
        mean = np.zeros(len(p))
        error = np.zeros(len(p))
        for i in range(len(p)):
            wo = -d[i]
            e1 = wo - (wo @ n[i]) * n[i]
            e1 = (
                e1 / np.linalg.norm(e1)
                if np.linalg.norm(e1) > 1e-12
                else np.cross(n[i], [1.0, 0.0, 0.0])
            )
            e1 /= np.linalg.norm(e1)
            e2 = np.cross(n[i], e1)
            x, y = sample_slopes(kind, alpha, rng.random(samples), rng.random(samples))
            h = n[i] + x[:, None] * e1 + y[:, None] * e2
            h /= np.linalg.norm(h, axis=1, keepdims=True)
            cos_h = h @ n[i]
            wo_h = h @ wo
            l_dir = 2.0 * wo_h[:, None] * h - wo
            cos_l, cos_o = l_dir @ n[i], wo @ n[i]
            # D(h) from the slope density: D = P22 / cos^4(theta_h); the sampled density of
            # h is D cos(theta_h), of l: D cos(theta_h) / (4 wo.h)
            big_d = slope_density(kind, alpha, x * x + y * y) / cos_h**4
            pdf_l = big_d * cos_h / (4.0 * np.abs(wo_h))
            g2 = 1.0 / (1.0 + smith_lambda(kind, alpha, cos_o) + smith_lambda(kind, alpha, cos_l))
            brdf = big_d * g2 / (4.0 * cos_o * np.where(cos_l > 0, cos_l, 1.0))
            uu, vv, landed = scene.active.emitter.coordinates(
                scene, np.broadcast_to(p[i], l_dir.shape), l_dir
            )
            seen = landed & (cos_l > 0) & (wo_h > 0)
            radiance = finish.mirror_radiance(scene, np.stack([uu, vv], axis=-1), seen)
            values = np.where(seen, radiance * brdf * cos_l / pdf_l, 0.0)
            mean[i] = values.mean()
            error[i] = values.std() / math.sqrt(samples)
        return mean, error


class Beckmann(Microfacet):
    name = "beckmann"
    rank = 2
    kernel = "gaussian"
    doc = "a Beckmann microfacet lobe of roughness alpha (Gaussian slopes)"


class GGX(Microfacet):
    name = "ggx"
    rank = 3
    kernel = "ggx"
    doc = "a GGX (Trowbridge-Reitz) microfacet lobe of roughness alpha (heavy-tailed slopes)"


COMPONENTS = (Beckmann, GGX)
