"""The reflection lobes' kernels at unit scale, shared by every lobe (the float64 twin of
``shaders/lib/kernels.glsl``): ``gaussian`` (``x ~ N(0, I)``: Blinn-Phong, Beckmann) and
``ggx`` (density ``1 / (π (1 + |x|²)²)``, GGX's slopes at ``α = 1``). A lobe lands on the
emitter as ``F x``, ``F`` its footprint (:meth:`ReflectionComponent.footprint
<glshade.components.base.ReflectionComponent.footprint>`)."""

from __future__ import annotations

import math

import numpy as np


def kernel_transfer(kernel: str, k: np.ndarray) -> np.ndarray:
    """The characteristic function of the unit kernel's marginal at angular frequency ``k``
    (per unit of the kernel's variable): ``exp(-k²/2)`` (``gaussian``) or ``k K1(k)``
    (``ggx``, 1 at 0)."""
    k = np.abs(np.asarray(k, np.float64))
    if kernel == "gaussian":
        return np.exp(-0.5 * k * k)
    from scipy.special import k1

    with np.errstate(invalid="ignore", over="ignore"):
        return np.where(k > 0.0, k * k1(np.where(k > 0.0, k, 1.0)), 1.0)


def half_frequency(kernel: str) -> float:
    """The ``k`` at which the kernel's transfer is 1/2: ``sqrt(2 ln 2)`` (``gaussian``),
    about 1.60 (``ggx``, ``k K1(k) = 1/2`` solved)."""
    if kernel == "gaussian":
        return math.sqrt(2.0 * math.log(2.0))
    from scipy.optimize import brentq

    return float(brentq(lambda k: float(kernel_transfer(kernel, np.array(k))) - 0.5, 1e-3, 20.0))


def lobe_frame(n: np.ndarray, wo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The tangent frame of a lobe about unit normals ``n`` (N, 3) seen from ``wo``: ``e1``
    towards ``wo`` (in the plane of incidence, the direction in which the emitter's
    coordinates mostly change), ``e2 = n × e1`` across; at normal incidence any
    perpendicular of ``n`` (the GLSL ``lobe_frame``'s choice)."""
    e1 = wo - np.einsum("nk,nk->n", wo, n)[:, None] * n
    norm = np.linalg.norm(e1, axis=1)
    degenerate = norm < 1e-12
    if degenerate.any():
        helper = np.where(
            np.abs(n[:, [0]]) < 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]])
        )
        e1 = np.where(degenerate[:, None], np.cross(n, helper), e1)
        norm = np.linalg.norm(e1, axis=1)
    e1 = e1 / norm[:, None]
    return e1, np.cross(n, e1)
