"""The Gaussian dent of paper eq. 2, ``D = -dmax exp(-1/2 p^T Σ^-1 p)``, ``p = (x-x0, z-z0)``.

Features: ``defect`` is ``none`` (dmax = 0: the first hit is the base surface's),
``isotropic`` (Σ = σ² I) or ``full``. GLSL: ``surface_hit_base.glsl``, or
``defect_isotropic.glsl`` / ``defect_full.glsl`` with the bracketed first-hit solve
``surface_hit_dent.glsl``. Oracle: depth, gradient, band, Mahalanobis breakpoints.

Scene files may give an isotropic Σ as one key, ``sigma2`` (written back that way).
"""

from __future__ import annotations

import math

import numpy as np

from glshade.components.base import DefectComponent
from glshade.errors import SceneError
from glshade.oracle.roots import stable_roots
from glshade.scene.params import Control, Param

DMAX = Param(
    "defect.dmax",
    "mm",
    0.005,
    "depth: > 0 a dent, < 0 a bump, 0 none",
    flag="--dmax",
    control=Control("dmax", -0.05, 0.05, fmt="%.4f mm"),
    plausible_max=0.1,
    plausible_why="deeper than the shallow dents glshade simulates",
)
SIGMA2 = Param(
    "defect.sigma2",
    "mm²",
    4.0,
    "isotropic variance: sets sigma_x2 = sigma_z2 = sigma2, sigma_xz = 0",
    lo=0.0,
    flag="--sigma2",
    control=Control("sigma2", 0.05, 100.0, log=True, fmt="%.2f mm2"),
    plausible_max=1e4,
    plausible_why="a dent over 100 mm wide",
    stored=False,
)
SIGMA_X2 = Param(
    "defect.sigma_x2",
    "mm²",
    4.0,
    "variance along x",
    lo=0.0,
    control=Control("sigma_x2", 0.05, 100.0, log=True, fmt="%.2f mm2"),
    plausible_max=1e4,
    plausible_why="a dent over 100 mm wide",
)
SIGMA_Z2 = Param(
    "defect.sigma_z2",
    "mm²",
    4.0,
    "variance along z",
    lo=0.0,
    control=Control("sigma_z2", 0.05, 100.0, log=True, fmt="%.2f mm2"),
    plausible_max=1e4,
    plausible_why="a dent over 100 mm wide",
)
SIGMA_XZ = Param(
    "defect.sigma_xz",
    "mm²",
    0.0,
    "covariance; |sigma_xz| < sqrt(sigma_x2 sigma_z2)",
    control=Control("sigma_xz", -100.0, 100.0, fmt="%.3f mm2"),
)
X0 = Param("defect.x0", "mm", 0.0, "centre, x", control=Control("x0", -15.0, 15.0, fmt="%.2f mm"))
Z0 = Param("defect.z0", "mm", 0.0, "centre, z", control=Control("z0", -15.0, 15.0, fmt="%.2f mm"))

#: Mahalanobis radii of the defect ellipses used as breakpoints by the tracer.
DEFECT_RADII = (1.0, 3.0, 8.5)
_COVARIANCE = ("sigma_x2", "sigma_z2", "sigma_xz")


def check_positive_definite(values: dict) -> None:
    sx2, sz2, sxz = values["sigma_x2"], values["sigma_z2"], values["sigma_xz"]
    if sxz * sxz >= sx2 * sz2:
        raise SceneError(
            "defect.sigma_xz",
            f"|sigma_xz| < sqrt(sigma_x2*sigma_z2) = {math.sqrt(sx2 * sz2):.6g} (covariance positive definite)",
            sxz,
        )


class Gaussian(DefectComponent):
    name = "gaussian"
    doc = "a Gaussian dent or bump (paper eq. 2)"
    params = (DMAX, SIGMA2, SIGMA_X2, SIGMA_Z2, SIGMA_XZ, X0, Z0)
    checks = (check_positive_definite,)

    # ------------------------------------------------------------------ files
    def read_file(self, values: dict, current: dict | None = None) -> dict:
        """``sigma2`` (isotropic) becomes the three covariance keys."""
        if "sigma2" not in values:
            return values
        clash = [k for k in _COVARIANCE if k in values]
        if clash:
            raise SceneError(f"defect.{clash[0]}", "absent when defect.sigma2 is given (isotropic)")
        values = dict(values)
        s2 = values.pop("sigma2")
        values["sigma_x2"] = values["sigma_z2"] = s2
        values.setdefault("sigma_xz", 0.0)
        return values

    def write_file(self, values: dict) -> dict:
        """An isotropic covariance is written as ``sigma2``."""
        if values.get("sigma_xz") != 0.0 or values.get("sigma_x2") != values.get("sigma_z2"):
            return values
        out = {"dmax": values["dmax"], "sigma2": values["sigma_x2"]}
        out.update((k, v) for k, v in values.items() if k not in ("dmax", *_COVARIANCE))
        return out

    # ------------------------------------------------------------------ shader
    def features(self, scene):
        d = scene.defect
        return {"defect": "none" if not d.present else ("isotropic" if d.isotropic else "full")}

    def glsl(self, variables):
        variant = variables["defect"]
        if variant == "none":
            return ("surface_hit_base.glsl",)
        return (f"defect_{variant}.glsl", "surface_hit_dent.glsl")

    def uniforms(self, scene, frame):
        variant = frame.variables["defect"]
        if variant == "none":
            return {}
        dent, solver = scene.defect, frame.solver
        inverse_variances = self._principal(dent)[1]
        values: dict[str, object] = {
            "u_dmax": dent.dmax,
            "u_dent_curvature": abs(dent.dmax) * max(inverse_variances),
            "u_dent_lo": min(0.0, -dent.dmax),
            "u_dent_hi": max(0.0, -dent.dmax),
            "u_march_steps": solver.march_steps,
            "u_newton_iterations": solver.newton_iterations,
            "u_root_tol": solver.tolerance_for(frame.variables["precision"]),
        }
        if variant == "isotropic":
            values["u_inv_sigma2"] = 1.0 / dent.sigma_x2
        else:
            values["u_cov_axis"], values["u_inv_var"] = self._principal(dent)
        return values

    @staticmethod
    def _principal(dent) -> tuple[tuple[float, float], tuple[float, float]]:
        """The first principal axis (x, z) and the inverse principal variances (1/mm²)."""
        variances, axes = np.linalg.eigh(
            np.array([[dent.sigma_x2, dent.sigma_xz], [dent.sigma_xz, dent.sigma_z2]])
        )
        return (float(axes[0, 0]), float(axes[1, 0])), (
            float(1.0 / variances[0]),
            float(1.0 / variances[1]),
        )

    # ------------------------------------------------------------------ oracle
    def present(self, scene):
        return scene.defect.present

    def centre(self, scene):
        return np.array([scene.defect.x0, 0.0, scene.defect.z0])

    def band(self, scene):
        return min(0.0, -scene.defect.dmax), max(0.0, -scene.defect.dmax)

    def depth(self, scene, x, z):
        """``D = -dmax exp(-1/2 p^T Σ^-1 p)`` (mm), ``p = (x - x0, z - z0)``."""
        defect = scene.defect
        if not defect.present:
            return np.zeros(np.broadcast(x, z).shape)
        ia, ib, ic = defect.inverse_covariance()
        px = x - defect.x0
        pz = z - defect.z0
        q = ia * px * px + 2.0 * ib * px * pz + ic * pz * pz
        return -defect.dmax * np.exp(-0.5 * q)

    def gradient(self, scene, x, z):
        """``(D_x, D_z)`` (dimensionless): ``∇D = -D Σ^-1 p``."""
        defect = scene.defect
        if not defect.present:
            zero = np.zeros(np.broadcast(x, z).shape)
            return zero, zero
        ia, ib, ic = defect.inverse_covariance()
        px = x - defect.x0
        pz = z - defect.z0
        d = self.depth(scene, x, z)
        return -d * (ia * px + ib * pz), -d * (ib * px + ic * pz)

    def breakpoints(self, scene, o, d):
        """The ray's crossings of the Mahalanobis ellipses ``q = 1, 9, 72.25`` (beyond the
        last the defect is below ``2e-16 |dmax|``)."""
        if not scene.defect.present:
            return []
        return [
            root
            for radius in DEFECT_RADII
            for root in self._ellipse_roots(scene.defect, o, d, radius)
        ]

    @staticmethod
    def _ellipse_roots(defect, o, d, radius):
        ia, ib, ic = defect.inverse_covariance()
        px, pz = o[:, 0] - defect.x0, o[:, 2] - defect.z0
        dx, dz = d[:, 0], d[:, 2]
        qa = ia * dx * dx + 2.0 * ib * dx * dz + ic * dz * dz
        qb = ia * px * dx + ib * (px * dz + pz * dx) + ic * pz * dz
        qc = ia * px * px + 2.0 * ib * px * pz + ic * pz * pz - radius * radius
        disc = qb * qb - qa * qc
        sqrt_disc = np.where(disc >= 0.0, np.sqrt(np.maximum(disc, 0.0)), np.nan)
        return list(stable_roots(qa, qb, qc, sqrt_disc))
