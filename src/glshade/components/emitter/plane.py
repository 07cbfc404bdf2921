"""The emitter's plane, shared by every emitter on it (the stripes, the fringes): its
uniforms (``lib/emitter_plane.glsl``) and where rays meet it (the float64 oracle)."""

from __future__ import annotations

from typing import Any

import numpy as np


def uniforms(scene: Any, context: Any) -> dict[str, object]:
    """The plane's uniforms, in the local frame of ``context.origin``."""
    em, plane, origin = scene.emitter, scene.emitter_plane(), context.origin
    return {
        "u_emitter_normal": tuple(plane.normal),
        "u_emitter_eu": tuple(plane.e_u),
        "u_emitter_ev": tuple(plane.e_v),
        "u_emitter_dist": em.distance,
        "u_emitter_offset": (
            float(origin @ plane.e_u),
            float(origin @ plane.e_v),
            float(origin @ plane.normal),
        ),
        "u_emitter_half": em.half_size,
    }


def coordinates(scene: Any, points: Any, directions: Any):
    """Where rays ``points + t r`` (mm; ``r`` need not be unit) meet the emitter.

    Returns ``(u, v, valid)``: screen coordinates in mm, shape (…); ``valid`` requires
    ``r·n_E < 0`` (towards the front), ``t_e > 0`` and ``|u|, |v| <= half_size``.
    ``u, v`` are NaN where not valid.
    """
    plane = scene.emitter_plane()
    p = np.asarray(points, dtype=np.float64)
    r = np.asarray(directions, dtype=np.float64)
    denom = r @ plane.normal
    rel = p - plane.centre
    with np.errstate(divide="ignore", invalid="ignore"):
        t_e = -(rel @ plane.normal) / denom
        q = rel + t_e[..., None] * r
    u = q @ plane.e_u
    v = q @ plane.e_v
    hu, hv = scene.emitter.half_size
    valid = (denom < 0.0) & (t_e > 0.0) & (np.abs(u) <= hu) & (np.abs(v) <= hv)
    return np.where(valid, u, np.nan), np.where(valid, v, np.nan), valid
