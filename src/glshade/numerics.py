"""Stable quadratic roots for the NumPy tracer and the components' oracles (float64)."""

from __future__ import annotations

import math

import numpy as np


def stable_roots(qa: np.ndarray, qb: np.ndarray, qc: np.ndarray, sqrt_disc: np.ndarray):
    """Roots ``t1 <= t2`` of ``qa t² + 2 qb t + qc = 0`` given ``sqrt(qb² - qa qc)``
    (NaN where negative/NaN or ``qa == 0``), without cancellation:
    ``q = -(qb + sign(qb) sqrt_disc)``, ``t = q / qa`` and ``qc / q``."""
    with np.errstate(divide="ignore", invalid="ignore"):
        q = -(qb + np.copysign(sqrt_disc, qb))
        t1 = q / qa
        t2 = np.where(q == 0.0, 0.0, qc / q)
        bad = ~np.isfinite(sqrt_disc) | (qa == 0.0)
        t1 = np.where(bad, np.nan, t1)
        t2 = np.where(bad, np.nan, t2)
    return np.minimum(t1, t2), np.maximum(t1, t2)


def circle_roots(oc: np.ndarray, dv: np.ndarray, radius: float):
    """Ray ``oc + t dv`` against the sphere/circle ``|p| = radius`` in ``k`` dims
    (``oc, dv``: (N, k)). The discriminant is ``qa (r² - |perp|²)`` with ``perp`` the
    closest-approach vector, computed as ``(r - |perp|)(r + |perp|)``: no cancellation
    between ``qb²`` and ``qa qc`` for rays passing close to the centre or far away."""
    qa = np.einsum("nk,nk->n", dv, dv)
    qb = np.einsum("nk,nk->n", oc, dv)
    qc = np.einsum("nk,nk->n", oc, oc) - radius * radius
    with np.errstate(divide="ignore", invalid="ignore"):
        tc = -qb / qa
        perp = np.linalg.norm(oc + tc[:, None] * dv, axis=1)
        inner = (radius - perp) * (radius + perp)
        sqrt_disc = np.where(inner >= 0.0, np.sqrt(qa * np.maximum(inner, 0.0)), np.nan)
    return stable_roots(qa, qb, qc, sqrt_disc)


def first_root_ahead(qa: np.ndarray, qb: np.ndarray, qc: np.ndarray) -> np.ndarray:
    """The smallest root ``t > 0`` of ``qa t² + 2 qb t + qc = 0`` (:func:`stable_roots`;
    where ``qa == 0`` the linear root), NaN where none lies ahead."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = stable_roots(qa, qb, qc, np.sqrt(qb * qb - qa * qc))
        linear = np.where(qa == 0.0, -qc / (2.0 * qb), np.nan)
    roots = np.stack([t1, t2, linear])
    roots[~(roots > 0.0)] = np.inf
    first = roots.min(axis=0)
    return np.where(np.isfinite(first), first, np.nan)


def nearest_root(qa: float, qb: float, qc: float, near: float) -> float:
    """The real root of ``qa t² + 2 qb t + qc = 0`` nearest ``near`` (:func:`stable_roots`;
    the linear root where ``qa == 0``); NaN where there is none."""
    if qa == 0.0:
        return -qc / (2.0 * qb) if qb != 0.0 else math.nan
    disc = qb * qb - qa * qc
    sqrt_disc = np.array(math.sqrt(disc) if disc >= 0.0 else math.nan)
    roots = stable_roots(np.array(qa), np.array(qb), np.array(qc), sqrt_disc)
    finite = [float(r) for r in roots if np.isfinite(r)]
    return min(finite, key=lambda r: abs(r - near)) if finite else math.nan
