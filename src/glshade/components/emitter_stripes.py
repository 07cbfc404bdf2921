"""The stripe emitter of SPEC §3: Gaussian stripes along ``u``, spaced along ``v``, in the
mirror position of the camera.

GLSL: ``emitter.glsl`` (where a reflected ray lands) and, when the image is wanted,
``stripes.glsl`` (the radiance there). Oracle: :meth:`Stripes.coordinates` and
:meth:`Stripes.radiance`.
"""

from __future__ import annotations

import math

import numpy as np

from glshade.components.base import EmitterComponent
from glshade.scene.params import Control, Param

#: FWHM of one stripe = half a period  =>  sigma = period / (4 sqrt(2 ln 2)).
STRIPE_SIGMA_PER_PERIOD = 1.0 / (4.0 * math.sqrt(2.0 * math.log(2.0)))

DISTANCE = Param("emitter.distance", "mm", 256.0, "origin to the emitter's centre", lo=0.0)
PERIOD = Param(
    "emitter.period",
    "mm",
    2.0,
    "stripe spacing along v",
    lo=0.0,
    flag="--period",
    control=Control("period", 0.2, 20.0, log=True, fmt="%.2f mm"),
)
STRIPE_SIGMA = Param(
    "emitter.stripe_sigma",
    "mm",
    None,
    "Gaussian width of one stripe (unset: FWHM = half a period)",
    lo=0.0,
    control=Control("stripe_sigma", 0.02, 10.0, log=True, fmt="%.3f mm"),
)
PHASE = Param(
    "emitter.phase",
    "mm",
    0.0,
    "shift of the stripes along v",
    flag="--phase",
    control=Control("phase", -1000.0, 1000.0, fmt="%.3f mm"),
)
HALF_SIZE = Param(
    "emitter.half_size", "mm", (150.0, 150.0), "half extents in u and v", value_type="pair"
)


class Stripes(EmitterComponent):
    name = "stripes"
    doc = "a plane of Gaussian stripes facing the origin, opposite the camera"
    params = (DISTANCE, PERIOD, STRIPE_SIGMA, PHASE, HALF_SIZE)

    def glsl(self, variables):
        return (
            ("emitter.glsl", "stripes.glsl")
            if "image" in variables["outputs"]
            else ("emitter.glsl",)
        )

    def uniforms(self, scene, frame):
        em, plane, origin = scene.emitter, scene.emitter_frame(), frame.origin
        values = {
            "u_em_normal": tuple(plane.normal),
            "u_em_eu": tuple(plane.e_u),
            "u_em_ev": tuple(plane.e_v),
            "u_em_dist": em.distance,
            "u_em_offset": (
                float(origin @ plane.e_u),
                float(origin @ plane.e_v),
                float(origin @ plane.normal),
            ),
            "u_em_half": em.half_size,
        }
        if "image" in frame.variables["outputs"]:
            values.update(u_period=em.period, u_stripe_sigma=em.sigma_mm, u_phase=em.phase)
        return values

    # ------------------------------------------------------------------ oracle
    def coordinates(self, scene, points, directions):
        """Where rays ``points + t r`` (mm; ``r`` need not be unit) meet the emitter.

        Returns ``(u, v, valid)``: screen coordinates in mm, shape (…); ``valid`` requires
        ``r·n_E < 0`` (towards the front), ``t_e > 0`` and ``|u|, |v| <= half_size``.
        ``u, v`` are NaN where not valid.
        """
        frame = scene.emitter_frame()
        p = np.asarray(points, dtype=np.float64)
        r = np.asarray(directions, dtype=np.float64)
        denom = r @ frame.normal
        rel = p - frame.centre
        with np.errstate(divide="ignore", invalid="ignore"):
            t_e = -(rel @ frame.normal) / denom
            q = rel + t_e[..., None] * r
        u = q @ frame.e_u
        v = q @ frame.e_v
        hu, hv = scene.emitter.half_size
        valid = (denom < 0.0) & (t_e > 0.0) & (np.abs(u) <= hu) & (np.abs(v) <= hv)
        return np.where(valid, u, np.nan), np.where(valid, v, np.nan), valid

    def radiance(self, scene, v) -> np.ndarray:
        return stripe_radiance(scene.emitter, v)


def stripe_radiance(emitter, v) -> np.ndarray:
    """Stripe radiance ``L(v) = Σ_k exp(-(v - phase - k period)² / (2 σ²))`` at ``v`` (mm).

    Every stripe within ``10σ`` of ``v`` is summed (at most one more, beyond, adds
    < exp(-50)).
    When more than 64 stripes would overlap (``σ > 3.1 period``) the identical Poisson
    form ``(σ sqrt(2π)/period) (1 + 2 Σ_m exp(-2π² σ² m²/period²) cos(2π m x/period))`` is
    used instead. NaN propagates.
    """
    v = np.asarray(v, dtype=np.float64)
    sigma = emitter.sigma_mm
    period = emitter.period
    x = v - emitter.phase
    span = 10.0 * sigma
    terms = int(math.floor(2.0 * span / period)) + 1  # stripes k with |x - k period| <= span
    if terms <= 64:
        with np.errstate(invalid="ignore"):
            k0 = np.ceil((x - span) / period)
        out = np.zeros_like(x)
        for j in range(terms):
            r = x - (k0 + j) * period
            out += np.exp(-(r * r) / (2.0 * sigma * sigma))
        return out
    ratio = sigma / period
    m_max = int(math.ceil(math.sqrt(45.0 / (2.0 * math.pi**2)) / ratio)) + 1  # exp(-45) ~ 3e-20
    phase = 2.0 * math.pi * x / period
    series = np.ones_like(x)
    for m in range(1, m_max + 1):
        series += 2.0 * math.exp(-2.0 * math.pi**2 * ratio**2 * m * m) * np.cos(m * phase)
    return ratio * math.sqrt(2.0 * math.pi) * series
