"""The Gaussian dent of paper eq. 2, ``D = -dmax exp(-1/2 p^T Σ^-1 p)``, ``p = (x-x0, z-z0)``.

Table: :class:`~glshade.components.defect.gaussian.table.Defect`. Features: ``defect`` is
``none`` (dmax = 0: the first hit is the base surface's), ``isotropic`` (Σ = σ² I) or
``full``. GLSL: ``hit_base.glsl``, or ``isotropic.glsl`` / ``full.glsl`` with the bracketed
first-hit solve ``hit_dent.glsl`` (built from the library's safe march and safeguarded
Newton). Oracle: depth, gradient, band, Mahalanobis breakpoints.

Scene files may give an isotropic Σ as one key, ``sigma2`` (written back that way).
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from glshade.components.base import DefectComponent, SceneView, UniformContext
from glshade.components.defect.gaussian.table import SIGMA2, Defect
from glshade.errors import SceneError
from glshade.numerics import stable_roots

#: Mahalanobis radii of the defect ellipses used as breakpoints by the tracer.
DEFECT_RADII = (1.0, 3.0, 8.5)
_COVARIANCE = ("sigma_x2", "sigma_z2", "sigma_xz")


class Gaussian(DefectComponent):
    name = "gaussian"
    doc = "a Gaussian dent or bump (paper eq. 2)"
    table = Defect
    shorthands = ((SIGMA2, "sigma_x2"),)

    # ------------------------------------------------------------------ files
    def read_file(
        self, values: dict[str, Any], current: dict[str, Any] | None = None
    ) -> dict[str, Any]:
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

    def write_file(self, values: dict[str, Any]) -> dict[str, Any]:
        """An isotropic covariance is written as ``sigma2``."""
        if values.get("sigma_xz") != 0.0 or values.get("sigma_x2") != values.get("sigma_z2"):
            return values
        out = {"dmax": values["dmax"], "sigma2": values["sigma_x2"]}
        out.update((k, v) for k, v in values.items() if k not in ("dmax", *_COVARIANCE))
        return out

    # ------------------------------------------------------------------ shader
    def features(self, scene: SceneView) -> dict[str, Hashable]:
        d = scene.defect
        return {"defect": "none" if not d.present else ("isotropic" if d.isotropic else "full")}

    def glsl(self, variables: Mapping[str, Hashable]) -> tuple[str, ...]:
        variant = variables["defect"]
        if variant == "none":
            return ("hit_base.glsl",)
        return (f"{variant}.glsl", "lib/march.glsl", "hit_dent.glsl")

    def uniforms(self, scene: SceneView, context: UniformContext) -> dict[str, object]:
        variant = context.variables["defect"]
        if variant == "none":
            return {}
        dent, solver = scene.defect, context.solver
        inverse_variances = self._principal(dent)[1]
        values: dict[str, object] = {
            "u_defect_dmax": dent.dmax,
            "u_defect_curvature": abs(dent.dmax) * max(inverse_variances),
            "u_defect_lo": min(0.0, -dent.dmax),
            "u_defect_hi": max(0.0, -dent.dmax),
            "u_defect_march_steps": solver.march_steps,
            "u_defect_newton_iterations": solver.newton_iterations,
            "u_defect_tol": solver.tolerance_for(context.variables["precision"]),
        }
        if variant == "isotropic":
            values["u_defect_inv_sigma2"] = 1.0 / dent.sigma_x2
        else:
            values["u_defect_axis"], values["u_defect_inv_var"] = self._principal(dent)
        return values

    def loop_iterations(self, scene: SceneView, solver: Any) -> int:
        # the march, then the Newton-bisection polish
        return (
            (solver.march_steps + 1) + (solver.newton_iterations + 1) if scene.defect.present else 0
        )

    @staticmethod
    def _principal(dent: Defect) -> tuple[tuple[float, float], tuple[float, float]]:
        """The first principal axis (x, z) and the inverse principal variances (1/mm²)."""
        variances, axes = np.linalg.eigh(
            np.array([[dent.sigma_x2, dent.sigma_xz], [dent.sigma_xz, dent.sigma_z2]])
        )
        return (float(axes[0, 0]), float(axes[1, 0])), (
            float(1.0 / variances[0]),
            float(1.0 / variances[1]),
        )

    # ------------------------------------------------------------------ oracle
    def present(self, scene: SceneView) -> bool:
        return scene.defect.present

    def centre(self, scene: SceneView) -> np.ndarray:
        return np.array([scene.defect.x0, 0.0, scene.defect.z0])

    def band(self, scene: SceneView) -> tuple[float, float]:
        return min(0.0, -scene.defect.dmax), max(0.0, -scene.defect.dmax)

    def depth(self, scene: SceneView, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        """``D = -dmax exp(-1/2 p^T Σ^-1 p)`` (mm), ``p = (x - x0, z - z0)``."""
        defect = scene.defect
        if not defect.present:
            return np.zeros(np.broadcast(x, z).shape)
        ia, ib, ic = defect.inverse_covariance()
        px = x - defect.x0
        pz = z - defect.z0
        q = ia * px * px + 2.0 * ib * px * pz + ic * pz * pz
        return -defect.dmax * np.exp(-0.5 * q)

    def gradient(
        self, scene: SceneView, x: np.ndarray, z: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
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

    def breakpoints(self, scene: SceneView, o: np.ndarray, d: np.ndarray) -> list[np.ndarray]:
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
    def _ellipse_roots(
        defect: Defect, o: NDArray[np.float64], d: NDArray[np.float64], radius: float
    ) -> list[NDArray[np.float64]]:
        ia, ib, ic = defect.inverse_covariance()
        px, pz = o[:, 0] - defect.x0, o[:, 2] - defect.z0
        dx, dz = d[:, 0], d[:, 2]
        qa = ia * dx * dx + 2.0 * ib * dx * dz + ic * dz * dz
        qb = ia * px * dx + ib * (px * dz + pz * dx) + ic * pz * dz
        qc = ia * px * px + 2.0 * ib * px * pz + ic * pz * pz - radius * radius
        disc = qb * qb - qa * qc
        sqrt_disc = np.where(disc >= 0.0, np.sqrt(np.maximum(disc, 0.0)), np.nan)
        return list(stable_roots(qa, qb, qc, sqrt_disc))


COMPONENTS = (Gaussian,)
