"""The Gaussian defect's table (paper eq. 2): depth, covariance and centre.

A scene file may give an isotropic covariance as one key, ``sigma2`` (:data:`SIGMA2`, a
shorthand the component expands); a scene file written by glshade does the same.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from glshade.errors import SceneError
from glshade.params import Control, Param, Table, param

_WIDE = "a dent over 100 mm wide"
#: The variances a dent may have, mm² (exclusive): from a micrometre wide to ten metres;
#: beyond them the covariance's inverse and determinant leave float64 (1e308 mm² made the
#: closed forms divide by zero).
VARIANCE_RANGE_MM2 = (1e-6, 1e8)
#: The largest depth or height of a dent, and the farthest centre, mm (exclusive).
DEPTH_LIMIT_MM = 1e3
CENTRE_LIMIT_MM = 1e4

SIGMA2 = Param(
    "defect.sigma2", "mm²", 4.0,
    "isotropic variance: sets sigma_x2 = sigma_z2 = sigma2, sigma_xz = 0",
    lo=VARIANCE_RANGE_MM2[0], hi=VARIANCE_RANGE_MM2[1],
    flag="--sigma2", control=Control("sigma2", 0.05, 100.0, log=True, fmt="%.2f mm2"),
    plausible_max=1e4, plausible_why=_WIDE, stored=False,
)  # fmt: skip


def check_positive_definite(values: dict[str, Any]) -> None:
    """The covariance is positive definite."""
    sx2, sz2, sxz = values["sigma_x2"], values["sigma_z2"], values["sigma_xz"]
    if sxz * sxz >= sx2 * sz2:
        raise SceneError(
            "defect.sigma_xz",
            f"|sigma_xz| < sqrt(sigma_x2*sigma_z2) = {math.sqrt(sx2 * sz2):.6g} "
            "(covariance positive definite)",
            sxz,
        )


@dataclass(frozen=True)
class Defect(Table):
    """The defect: ``dmax`` (mm; > 0 dent, < 0 bump, 0 none), the covariance ``sigma_x2``,
    ``sigma_z2``, ``sigma_xz`` (mm², positive definite), the centre ``x0``, ``z0`` (mm)."""

    table = "defect"
    table_checks = (check_positive_definite,)

    dmax: float = param(
        "defect.dmax", "mm", 0.005, "depth: > 0 a dent, < 0 a bump, 0 none", flag="--dmax",
        lo=-DEPTH_LIMIT_MM, hi=DEPTH_LIMIT_MM,
        control=Control("dmax", -0.05, 0.05, fmt="%.4f mm"), plausible_max=0.1,
        plausible_why="deeper than the shallow dents glshade simulates",
    )  # fmt: skip
    sigma_x2: float = param(
        "defect.sigma_x2", "mm²", 4.0, "variance along x",
        lo=VARIANCE_RANGE_MM2[0], hi=VARIANCE_RANGE_MM2[1],
        control=Control("sigma_x2", 0.05, 100.0, log=True, fmt="%.2f mm2"),
        plausible_max=1e4, plausible_why=_WIDE,
    )  # fmt: skip
    sigma_z2: float = param(
        "defect.sigma_z2", "mm²", 4.0, "variance along z",
        lo=VARIANCE_RANGE_MM2[0], hi=VARIANCE_RANGE_MM2[1],
        control=Control("sigma_z2", 0.05, 100.0, log=True, fmt="%.2f mm2"),
        plausible_max=1e4, plausible_why=_WIDE,
    )  # fmt: skip
    sigma_xz: float = param(
        "defect.sigma_xz", "mm²", 0.0, "covariance; |sigma_xz| < sqrt(sigma_x2 sigma_z2)",
        control=Control("sigma_xz", -100.0, 100.0, fmt="%.3f mm2"),
    )  # fmt: skip
    x0: float = param(
        "defect.x0", "mm", 0.0, "centre, x", lo=-CENTRE_LIMIT_MM, hi=CENTRE_LIMIT_MM,
        control=Control("x0", -15.0, 15.0, fmt="%.2f mm"),
    )  # fmt: skip
    z0: float = param(
        "defect.z0", "mm", 0.0, "centre, z", lo=-CENTRE_LIMIT_MM, hi=CENTRE_LIMIT_MM,
        control=Control("z0", -15.0, 15.0, fmt="%.2f mm"),
    )  # fmt: skip

    @classmethod
    def isotropic_dent(cls, dmax: float, sigma2: float, x0: float = 0.0, z0: float = 0.0) -> Defect:
        return cls(dmax=dmax, sigma_x2=sigma2, sigma_z2=sigma2, sigma_xz=0.0, x0=x0, z0=z0)

    def clamp(self, name: str, value: Any) -> Any:
        """The covariance positive definite."""
        if name != "sigma_xz":
            return value
        bound = 0.999 * math.sqrt(self.sigma_x2 * self.sigma_z2)
        return min(max(value, -bound), bound)

    @property
    def present(self) -> bool:
        return self.dmax != 0.0

    @property
    def isotropic(self) -> bool:
        return self.sigma_xz == 0.0 and self.sigma_x2 == self.sigma_z2

    def inverse_covariance(self) -> tuple[float, float, float]:
        """``(a, b, c)`` with ``Σ^-1 = [[a, b], [b, c]]`` in 1/mm², float64."""
        det = self.sigma_x2 * self.sigma_z2 - self.sigma_xz * self.sigma_xz
        return self.sigma_z2 / det, -self.sigma_xz / det, self.sigma_x2 / det
