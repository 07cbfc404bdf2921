"""Blinn-Phong reflection: the weight ``(n·h)^N`` around the mirror direction,
normalised so that a uniform emitter gives 1.

Table: :class:`BlinnPhongTable` (the exponent, and the finish of eq. (1)). GLSL:
``blinn_phong.glsl`` (a Gaussian lobe: the emitter's pattern seen through a Gaussian, exact
as N -> infinity, paraxial otherwise). Oracle: :meth:`BlinnPhong.shade`, a brute-force
midpoint quadrature of ``∫ L w dω_l / ∫ w dω_l`` over the half vector (the method and its
error budget are in :mod:`glshade.oracle.tracer`'s docstring).
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, cast

import numpy as np
from numpy.typing import NDArray

from glshade.components.base import ReflectionComponent, SceneView, UniformContext
from glshade.components.emitter.plane import sag_coefficients, sag_distance, sag_of
from glshade.components.reflection import finish
from glshade.components.reflection.kernels import lobe_frame
from glshade.errors import SceneError
from glshade.params import Control, param

if TYPE_CHECKING:  # the knob is imported when asked for
    from glshade.components.reflection.blinn_phong.accuracy import BlinnPhongKnob

#: The default exponent: the lobe (reflected-direction std ``2/√N`` = 0.63 mrad) blurs
#: the paper's 2 mm stripes seen 256 mm away by ±0.16 mm, keeping 88 % of their contrast.
DEFAULT_SHININESS = 1e7


@dataclass(frozen=True)
class BlinnPhongTable(finish.FinishTable):
    """The Blinn-Phong exponent (and the finish of eq. (1))."""

    shininess: float = param(
        "render.shininess", "", DEFAULT_SHININESS,
        "Blinn-Phong exponent N (the reflected direction's angular std is 2/sqrt(N) rad; "
        "stripes of period P seen L mm away wash out below N = (8 L / P)^2)",
        lo=0.0, flag="--shininess", control=Control("shininess", 100.0, 1e10, log=True, fmt="%.3g"),
    )  # fmt: skip


#: Blinn-Phong box half-width in lobe standard deviations (of the half vector's angle,
#: 1/sqrt(n)): the weight beyond is below exp(-32).
_LOBE_SPAN_STD = 8.0
#: The box's half-width is capped at this angle (rad) from the normal.
_LOBE_MAX_ANGLE = 1.3
#: Blinn-Phong grid points per lobe standard deviation (midpoint rule on a Gaussian of
#: std s with step s/2 errs by ~2 exp(-8π²) ~ 1e-34 relative).
_LOBE_POINTS_PER_STD = 2.0
#: Blinn-Phong grid points per stripe sigma on the emitter, at the steepest ∂v/∂(a, b)
#: (step σ/1.25, with the slope safety below σ/1.5: aliasing ~2 exp(-2π² 1.5²) ~ 1e-19).
_STRIPE_POINTS_PER_SIGMA = 1.25
#: Margin on the slope of v measured on a 9 x 9 coarse grid of the box.
_SLOPE_SAFETY = 1.2
#: Minimum grid points per axis of the Blinn-Phong quadrature.
_LOBE_MIN_POINTS = 48
#: Most grid points per axis (beyond it the call is refused rather than under-resolved).
_LOBE_MAX_POINTS = 8192
#: Work-array budget (grid points x pixels) of one Blinn-Phong batch.
_LOBE_BATCH = 1_000_000
#: The smallest Blinn-Phong exponent whose lobe (8 std) fits the gnomonic box.
MIN_SHININESS = 50.0


class BlinnPhong(ReflectionComponent):
    name = "blinn-phong"
    rank = 1
    doc = "a Blinn-Phong lobe of exponent N around the mirror direction"
    table = BlinnPhongTable

    def features(self, scene: SceneView) -> dict[str, Hashable]:
        return finish.features(scene, kernel="gaussian", filtered=True)

    def glsl(self, variables: Mapping[str, Hashable]) -> tuple[str, ...]:
        return finish.glsl(variables, "blinn_phong.glsl")

    def uniforms(self, scene: SceneView, context: UniformContext) -> dict[str, object]:
        if not context.variables["shading"]:
            return {}
        values = finish.uniforms(scene, context.variables)
        return {"u_reflection_shininess": cast(BlinnPhongTable, scene.render).shininess, **values}

    def loop_iterations(self, scene: SceneView, solver: Any) -> int:
        return 1  # the end of its loop over the patterns

    def pattern_loop_iterations(self, scene: SceneView, solver: Any) -> int:
        return 1  # each pattern once

    def keeps_emitter_scale(self, scene: SceneView) -> bool:
        return not finish.coherence_on(scene)

    def shade(
        self,
        scene: SceneView,
        p: np.ndarray,
        d: np.ndarray,
        n: np.ndarray,
        uv: np.ndarray,
        ok: np.ndarray,
    ) -> np.ndarray:
        lobe = _blinn_phong(scene, p, d, n)
        if not finish.coherence_on(scene):
            return lobe
        return finish.mix_coherent(scene, finish.mirror_radiance(scene, uv, ok), lobe, d, n)

    def accuracy_knob(self) -> BlinnPhongKnob:
        # imported here: the knob is only run by `glshade accuracy`
        from glshade.components.reflection.blinn_phong.accuracy import BlinnPhongKnob

        return BlinnPhongKnob()

    def footprint(
        self, scene: SceneView, p: np.ndarray, d: np.ndarray, n: np.ndarray
    ) -> tuple[np.ndarray, str] | None:
        """``J (2 a, 2 cos i b) / √N``: the reflected direction's Gaussian spread in (``a``)
        and across (``b``) the plane of incidence, through the emitter's Jacobian ``J``."""
        r = d - 2.0 * np.einsum("nk,nk->n", d, n)[:, None] * n
        b = np.cross(n, r)
        length = np.linalg.norm(b, axis=1)
        helper = np.where(
            np.abs(r[:, [0]]) < 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]])
        )
        across = np.cross(r, helper)
        b = np.where(length[:, None] > 1e-6, b, across)
        b /= np.linalg.norm(b, axis=1, keepdims=True)
        a = np.cross(b, r)
        cos_i = -np.einsum("nk,nk->n", d, n)
        scale = 2.0 / math.sqrt(cast(BlinnPhongTable, scene.render).shininess)
        emitter = scene.active.emitter
        return emitter.jacobian(scene, p, r, scale * a, (scale * cos_i)[:, None] * b), "gaussian"

    def finish_name(self, scene: SceneView) -> str:
        return f"blinn-phong, shininess {cast(BlinnPhongTable, scene.render).shininess:.3g}"

    def lobe_std_rad(self, scene: SceneView) -> float:
        """``(n·h)^N ≈ exp(-N α²/2)``: the half vector's angle has std ``1/√N``, the
        reflected direction twice that."""
        return 2.0 / math.sqrt(cast(BlinnPhongTable, scene.render).shininess)

    def sharpen_hint(self, scene: SceneView, ratio: float) -> str:
        return f"render.shininess >= {cast(BlinnPhongTable, scene.render).shininess * ratio**2:.3g}"


def _lobe_samples(
    scene: SceneView,
    p: NDArray[np.float64],
    wo: NDArray[np.float64],
    n_s: NDArray[np.float64],
    e1: NDArray[np.float64],
    e2: NDArray[np.float64],
    a: NDArray[np.float64],
    b: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """Weights ``∝ w dω_l`` and the emitter's ``u``, ``v`` (mm) and validity at the gnomonic
    half-vector offsets ``(a, b)`` (grid arrays (1, n1, n2)) for the N pixels of ``p``.

    ``h = (n + a e1 + b e2)/sqrt(1 + a² + b²)`` (unit: the basis is orthonormal), so
    ``n·h = (1 + a² + b²)^{-1/2}``, ``dω_h = da db (1 + a² + b²)^{-3/2}`` and the weight
    ``(n·h)^n 4 (wo·h) dω_h / (da db)`` is ``(1 + a² + b²)^{-(n+3)/2} 4 max(wo·h, 0)``. The
    direction ``l = 2 (wo·h) h - wo`` is needed only through its dot products with the
    emitter's axes, which are linear in ``(a, b)``: no 3-vectors per sample.
    """
    plane = scene.emitter_plane()
    shininess = cast(BlinnPhongTable, scene.render).shininess
    rr = 1.0 + a * a + b * b
    inv = 1.0 / np.sqrt(rr)
    base = np.exp(-0.5 * (shininess + 3.0) * np.log(rr))

    def along(x: np.ndarray) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(h·x, wo·x)`` for a fixed vector ``x``, per pixel and sample."""
        hx = (
            (n_s @ x)[:, None, None] + a * (e1 @ x)[:, None, None] + b * (e2 @ x)[:, None, None]
        ) * inv
        return hx, (wo @ x)[:, None, None]

    wo_h = (
        np.einsum("nk,nk->n", wo, n_s)[:, None, None]
        + a * np.einsum("nk,nk->n", wo, e1)[:, None, None]
        + b * np.einsum("nk,nk->n", wo, e2)[:, None, None]
    ) * inv
    weight = base * 4.0 * np.maximum(wo_h, 0.0)
    h_n, wo_n = along(plane.normal)
    h_v, wo_v = along(plane.e_v)
    h_u, wo_u = along(plane.e_u)
    l_n = 2.0 * wo_h * h_n - wo_n  # l·n_E
    l_u, l_v = 2.0 * wo_h * h_u - wo_u, 2.0 * wo_h * h_v - wo_v
    rel = p - plane.centre
    glass = scene.active.emitter.cover_glass(scene)
    thickness = glass[0] if glass is not None else 0.0
    sag = sag_of(scene)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_e = (thickness - rel @ plane.normal)[:, None, None] / l_n
        if sag is not None:  # onto the sagging screen (the plane's sag_distance)
            foot = ((rel @ plane.e_u)[:, None, None], (rel @ plane.e_v)[:, None, None])
            gap = (thickness - rel @ plane.normal)[:, None, None]
            coefficients = sag_coefficients(sag, scene.emitter.half_size)
            t_e = sag_distance(coefficients, foot, (l_u, l_v), l_n, gap, t_e)
        v = (rel @ plane.e_v)[:, None, None] + t_e * l_v
        u = (rel @ plane.e_u)[:, None, None] + t_e * l_u
        if glass is not None:  # through the cover glass to the emitting layer (l is unit)
            cos_r = np.sqrt(np.maximum(1.0 - (l_u**2 + l_v**2) / glass[1] ** 2, 0.0))
            u = u + thickness * l_u / (glass[1] * cos_r)
            v = v + thickness * l_v / (glass[1] * cos_r)
    hu, hv = scene.emitter.half_size
    ok = (l_n < 0.0) & (t_e > 0.0) & (np.abs(u) <= hu) & (np.abs(v) <= hv) & (wo_h > 0.0)
    return weight, u, v, ok


def _grid_points(
    scene: SceneView,
    p: NDArray[np.float64],
    wo: NDArray[np.float64],
    n_s: NDArray[np.float64],
    e1: NDArray[np.float64],
    e2: NDArray[np.float64],
    half: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel grid sizes ``(N1, N2)`` along ``(e1, e2)`` that resolve the lobe and the
    stripes, rounded up to multiples of 16 (pixels with equal sizes share a batch).
    ``v`` is sampled on a 9 x 9 coarse grid of each box to bound its slopes."""
    shininess = cast(BlinnPhongTable, scene.render).shininess
    step_lobe = 1.0 / (math.sqrt(shininess) * _LOBE_POINTS_PER_STD)
    n_lobe = 2.0 * half / step_lobe
    c = np.linspace(-1.0, 1.0, 9) * half
    a, b = np.meshgrid(c, c, indexing="ij")
    _, u, v, ok = _lobe_samples(scene, p, wo, n_s, e1, e2, a[None], b[None])
    v = scene.active.emitter.along(scene, u, v)  # the coordinate the pattern varies along
    step = 2.0 * half / 8.0
    with np.errstate(invalid="ignore"):
        dv1 = np.where(ok[:, 1:, :] & ok[:, :-1, :], np.abs(np.diff(v, axis=1)), 0.0) / step
        dv2 = np.where(ok[:, :, 1:] & ok[:, :, :-1], np.abs(np.diff(v, axis=2)), 0.0) / step
    feature = scene.active.emitter.feature_mm(scene)
    h_v = feature / _STRIPE_POINTS_PER_SIGMA
    sizes = []
    for slope in (dv1.max(axis=(1, 2)), dv2.max(axis=(1, 2))):
        wanted = np.maximum(max(_LOBE_MIN_POINTS, n_lobe), _SLOPE_SAFETY * slope * 2.0 * half / h_v)
        if wanted.max() > _LOBE_MAX_POINTS:
            raise SceneError(
                "render.shininess",
                f"large enough for the NumPy reference's Blinn-Phong grid ({wanted.max():.0f} "
                "points per "
                f"axis needed to resolve the emitter's {feature:g} mm features; limit "
                f"{_LOBE_MAX_POINTS})",
                shininess,
            )
        sizes.append((16 * np.ceil(wanted / 16.0)).astype(np.int64))
    return sizes[0], sizes[1]


def _blinn_phong(scene: SceneView, p: np.ndarray, d: np.ndarray, n_s: np.ndarray) -> np.ndarray:
    """Blinn-Phong pixel values at hit points ``p`` (N, 3) for unit camera directions ``d``
    and normals ``n_s``: brute-force midpoint quadrature of ``∫ L w dω_l / ∫ w dω_l`` over
    the half vector (see the module docstring)."""
    shininess = cast(BlinnPhongTable, scene.render).shininess
    if shininess < MIN_SHININESS:
        raise SceneError(
            "render.shininess",
            f">= {MIN_SHININESS:g} for the NumPy reference's Blinn-Phong quadrature",
            shininess,
        )
    out = np.zeros(len(p))
    if not len(p):
        return out
    wo = -d
    e1, e2 = lobe_frame(n_s, wo)
    half = math.tan(min(_LOBE_SPAN_STD / math.sqrt(shininess), _LOBE_MAX_ANGLE))
    sizes1, sizes2 = _grid_points(scene, p, wo, n_s, e1, e2, half)
    for n1, n2 in sorted(set(zip(sizes1.tolist(), sizes2.tolist(), strict=False))):
        group = np.nonzero((sizes1 == n1) & (sizes2 == n2))[0]
        a = (-1.0 + (2.0 * np.arange(n1) + 1.0) / n1) * half  # midpoints of [-half, half]
        b = (-1.0 + (2.0 * np.arange(n2) + 1.0) / n2) * half
        a, b = np.meshgrid(a, b, indexing="ij")
        batch = max(1, _LOBE_BATCH // (n1 * n2))
        for s in range(0, len(group), batch):
            idx = group[s : s + batch]
            weight, u, v, ok = _lobe_samples(
                scene, p[idx], wo[idx], n_s[idx], e1[idx], e2[idx], a[None], b[None]
            )
            lum = finish.mirror_radiance(scene, np.stack([u, v], axis=-1), ok)
            out[idx] = np.sum(lum * weight, axis=(1, 2)) / np.sum(weight, axis=(1, 2))
    return out


COMPONENTS = (BlinnPhong,)
