"""The emitter's plane, shared by every emitter on it (the stripes, the fringes): its
uniforms (``lib/emitter_plane.glsl``) and where rays meet it (the float64 oracle)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

#: Newton steps that take a ray's hit from the plane onto a sagging screen (the GLSL's
#: ``emitter_sag_hit`` takes as many; :func:`sag_distance`).
SAG_STEPS = 3


def sag_of(scene: Any) -> tuple[float, float, float] | None:
    """The screen's sag ``(bow_u, bow_v, twist)`` (mm, ``emitter.sag``), None for a flat
    screen (the ``screen_sag`` feature: its GLSL is absent then)."""
    sag = getattr(scene.emitter, "sag", None)
    if sag is None or not any(sag):
        return None
    bow_u, bow_v, twist = (float(c) for c in sag)
    return bow_u, bow_v, twist


def sag_coefficients(
    sag: tuple[float, float, float], half_size: tuple[float, float]
) -> tuple[float, float, float]:
    """``(a, b, c)`` (1/mm) of ``w(u, v) = a u² + b v² + c u v``: ``bow_u / half_u²``,
    ``bow_v / half_v²``, ``twist / (half_u half_v)`` (the uniform ``u_emitter_sag``)."""
    hu, hv = half_size
    return sag[0] / (hu * hu), sag[1] / (hv * hv), sag[2] / (hu * hv)


def sag_height(coefficients: tuple[float, float, float], u: Any, v: Any) -> Any:
    """``w(u, v)`` (mm, towards the viewer) of the sag's ``coefficients``."""
    a, b, c = coefficients
    return u * (a * u + c * v) + b * v * v


def sag_gradient(coefficients: tuple[float, float, float], u: Any, v: Any) -> tuple[Any, Any]:
    """``(∂w/∂u, ∂w/∂v)`` of the sag's ``coefficients``."""
    a, b, c = coefficients
    return 2.0 * a * u + c * v, 2.0 * b * v + c * u


def sag_distance(
    coefficients: tuple[float, float, float],
    foot: tuple[Any, Any],
    along: tuple[Any, Any],
    facing: Any,
    gap: Any,
    distance: Any,
) -> Any:
    """The ray parameter where rays ``p + d r`` meet the plane ``gap`` ahead of them raised
    by the sag, from their plane hit ``distance`` (``= gap / facing``; ``gap`` is the level's
    height minus the point's, along the plane's normal): :data:`SAG_STEPS` Newton steps on
    ``f(d) = d (r·n) - gap - w(foot + d along)``, ``along = (r·e_u, r·e_v)``, ``foot`` the
    point's own ``(u, v)``, ``facing = r·n``.

    Convergence: from the plane the error is ``|w| / |r·n|`` and each step squares it,
    ``|e_{k+1}| ≈ (along·H·along / 2 |f'|) e_k²`` (``H`` the sag's Hessian, ``f' = r·n -
    ∇w·along``). Measured on rays 250 mm from a 150 mm half-size screen: a 1 mm bow leaves
    2e-4 mm after one step and < 1e-11 mm after two, up to 60° from the normal; the
    largest sag allowed (15 mm) leaves < 1e-11 mm after three within 45° of the normal,
    1e-6 mm at 60°."""
    u0, v0 = foot
    au, av = along
    d = distance
    for _ in range(SAG_STEPS):
        u, v = u0 + d * au, v0 + d * av
        wu, wv = sag_gradient(coefficients, u, v)
        f = d * facing - gap - sag_height(coefficients, u, v)
        d = d - f / (facing - (wu * au + wv * av))
    return d


def uniforms(scene: Any, context: Any) -> dict[str, object]:
    """The plane's uniforms, in the local frame of ``context.origin`` (and where the screen
    sags, ``u_emitter_sag``: :func:`sag_coefficients`)."""
    em, plane, origin = scene.emitter, scene.emitter_plane(), np.asarray(context.origin)
    values: dict[str, object] = {
        "u_emitter_normal": tuple(plane.normal),
        "u_emitter_eu": tuple(plane.e_u),
        "u_emitter_ev": tuple(plane.e_v),
        "u_emitter_dist": plane.distance,
        "u_emitter_offset": (
            float(origin @ plane.e_u) - plane.offset_uv[0],
            float(origin @ plane.e_v) - plane.offset_uv[1],
            float(origin @ plane.normal),
        ),
        "u_emitter_half": em.half_size,
    }
    sag = sag_of(scene)
    if sag is not None:
        values["u_emitter_sag"] = sag_coefficients(sag, em.half_size)
    return values


def coordinates(
    scene: Any, points: Any, directions: Any, glass: tuple[float, float] | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """Where rays ``points + t r`` (mm; ``r`` need not be unit) meet the emitter.

    Returns ``(u, v, valid)``: screen coordinates in mm, shape (…); ``valid`` requires
    ``r·n_E < 0`` (towards the front), ``t_e > 0`` and ``|u|, |v| <= half_size``.
    ``u, v`` are NaN where not valid. ``glass``: a cover glass ``(thickness mm, index)`` in
    front of the emitting layer: the ray meets its front face ``thickness`` nearer the
    origin, refracts (``sin r = sin i / n``) and meets the layer ``t tan r`` from there along
    its plane of incidence.

    A sagging screen (``emitter.sag``, :func:`sag_of`): the ray meets the surface ``plane +
    w(u, v) n`` (its front face ``plane + (thickness + w) n`` under a cover glass, which
    then refracts as a flat glass would), found from the plane's hit by
    :func:`sag_distance`; ``(u, v)`` is the hit's foot on the plane.
    """
    plane = scene.emitter_plane()
    p = np.asarray(points, np.float64)
    r = np.asarray(directions, np.float64)
    if glass is not None:
        r = r / np.linalg.norm(r, axis=-1, keepdims=True)
    denom = r @ plane.normal
    rel = p - plane.centre
    thickness = glass[0] if glass is not None else 0.0
    sag = sag_of(scene)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_e = (thickness - rel @ plane.normal) / denom
        if sag is not None:
            coefficients = sag_coefficients(sag, scene.emitter.half_size)
            foot = (rel @ plane.e_u, rel @ plane.e_v)
            lean = (r @ plane.e_u, r @ plane.e_v)
            gap = thickness - rel @ plane.normal
            t_e = sag_distance(coefficients, foot, lean, denom, gap, t_e)
        q = rel + t_e[..., None] * r
    u = q @ plane.e_u
    v = q @ plane.e_v
    if glass is not None:
        along = np.stack([r @ plane.e_u, r @ plane.e_v], axis=-1)  # sin i along the face
        index = glass[1]
        cos_r = np.sqrt(np.maximum(1.0 - np.sum(along**2, axis=-1) / index**2, 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            inside = thickness * along / (index * cos_r[..., None])
        u, v = u + inside[..., 0], v + inside[..., 1]
    hu, hv = scene.emitter.half_size
    valid = (denom < 0.0) & (t_e > 0.0) & (np.abs(u) <= hu) & (np.abs(v) <= hv)
    return np.where(valid, u, np.nan), np.where(valid, v, np.nan), valid


def form_factor(scene: Any, p: np.ndarray, n: np.ndarray, points: int = 96) -> np.ndarray:
    """``(1/π) ∫ cos θs cos θe / r² dA`` over the emitter rectangle seen from hits ``p``
    (N, 3) with unit normals ``n``, the part below the tangent plane left out, by
    Gauss–Legendre quadrature on the rectangle (``points``² nodes; the clipping kink limits
    it to ~1e-5), independently of the shader's closed polygon formula."""
    plane = scene.emitter_plane()
    hu, hv = scene.emitter.half_size
    x, w = np.polynomial.legendre.leggauss(points)
    uu, vv = np.meshgrid(x * hu, x * hv, indexing="ij")
    weights = np.outer(w, w).ravel() * hu * hv
    q = plane.centre + uu.ravel()[:, None] * plane.e_u + vv.ravel()[:, None] * plane.e_v  # (M, 3)
    out = np.empty(len(p))
    for i in range(len(p)):
        out[i] = np.sum(weights * lambert_kernel(plane, q - p[i], n[i])) / math.pi
    return out


def lambert_kernel(plane: Any, to_screen: np.ndarray, n: np.ndarray) -> np.ndarray:
    """``cos θs cos θe / r²`` (per mm² of screen) from a hit with unit normal ``n`` to the
    screen points ``to_screen`` away (…, 3); 0 below the tangent plane or behind the
    screen."""
    dist2 = np.einsum("...k,...k->...", to_screen, to_screen)
    cos_s = np.maximum(to_screen @ n, 0.0) / np.sqrt(dist2)
    cos_e = np.maximum(-(to_screen @ plane.normal), 0.0) / np.sqrt(dist2)
    return cos_s * cos_e / dist2


def jacobian(
    scene: Any,
    points: np.ndarray,
    r: np.ndarray,
    a1: np.ndarray,
    a2: np.ndarray,
    glass: tuple[float, float] | None = None,
) -> np.ndarray:
    """How the landing point ``(u, v)`` of rays ``points + t r`` (unit ``r``, (N, 3)) moves
    as they turn: ``J`` (N, 2, 2), column ``j`` the derivative along ``r + ε a_j`` (mm per
    radian for a unit ``a_j`` orthogonal to ``r``); the float64 oracle of the GLSL
    ``emitter_jacobian``. By central differences of :func:`coordinates` (step 1e-6 rad:
    truncation ~1e-12, rounding ~1e-10 of the distance)."""
    step = 1e-6
    out = np.empty((len(r), 2, 2))
    for column, a in enumerate((a1, a2)):
        length = np.linalg.norm(a, axis=-1)
        unit = a / np.where(length > 0.0, length, 1.0)[:, None]
        ahead = coordinates(scene, points, r + step * unit, glass)
        behind = coordinates(scene, points, r - step * unit, glass)
        out[:, 0, column] = length * (ahead[0] - behind[0]) / (2.0 * step)
        out[:, 1, column] = length * (ahead[1] - behind[1]) / (2.0 * step)
    return out
