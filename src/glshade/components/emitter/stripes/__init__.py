"""The stripe emitter: Gaussian stripes along ``u``, spaced along ``v``, on a plane in the
mirror position of the camera (it moves with the camera's elevation and the rig's azimuth).

Table and pattern: :class:`~glshade.components.emitter.stripes.table.Emitter`. GLSL:
``plane.glsl`` (where a reflected ray lands, how fast ``v`` moves), ``stripes.glsl`` (the
radiance, and the stripes seen through a Gaussian or GGX lobe) and ``diffuse.glsl`` (a
Lambertian reflection of the whole emitter), each only where the program needs it.
Oracle: :meth:`Stripes.coordinates` and the pattern's radiance.
"""

from __future__ import annotations

import numpy as np

from glshade.components.base import EmitterComponent
from glshade.components.emitter.stripes.table import Emitter


class Stripes(EmitterComponent):
    name = "stripes"
    doc = "a plane of Gaussian stripes facing the origin, opposite the camera"
    table = Emitter

    def glsl(self, variables):
        if "image" not in variables["outputs"]:
            return ("plane.glsl",)
        return ("plane.glsl", "stripes.glsl", *(("diffuse.glsl",) if variables["diffuse"] else ()))

    def uniforms(self, scene, context):
        em, plane, origin = scene.emitter, scene.emitter_plane(), context.origin
        values: dict[str, object] = {
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
        if "image" in context.variables["outputs"]:
            values.update(
                u_emitter_period=em.period, u_emitter_sigma=em.sigma_mm, u_emitter_phase=em.phase
            )
            if context.variables["diffuse"]:
                values["u_emitter_mean"] = em.mean_radiance()
        return values

    def loop_iterations(self, scene, solver):
        # once per ray: the GGX blur's harmonics (at most 64), the diffuse polygon (at most 5)
        variables = scene.active.features(scene)
        return (65 if variables.get("blur") == "ggx" else 0) + (
            6 if variables.get("diffuse") else 0
        )

    def pattern(self, scene) -> Emitter:
        return scene.emitter

    # ------------------------------------------------------------------ oracle
    def coordinates(self, scene, points, directions):
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


COMPONENTS = (Stripes,)
