"""The real station beside its twin (docs/twin.md): the part's deviation (measured
slopes less the nominal and the fitted parabola's, the measured screen points less the
twin's), and the twin's frames beside the real ones (modulation per period, offset,
the noise the fit residual implies)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from glshade.capture.sofast import SofastDecoded, SofastMeasurement
from glshade.twin.reconstruct import FacetMeasurement
from glshade.twin.scene import TwinFrames


@dataclass(frozen=True)
class Deviation:
    """Maps (H, W; NaN off the facet): ``from_design`` and ``from_fit`` (2, H, W) the
    measured slopes less the design parabola's and the fitted one's at the same points
    (rad); ``screen_mm`` (2, H, W) the measured screen points less the twin's (mm,
    screen coordinates, NaN where the twin's ray misses the screen); ``from_twin`` (2, H,
    W) the measured slopes less the twin's frames reconstructed alike (rad)."""

    from_design: NDArray[np.float64]
    from_fit: NDArray[np.float64]
    screen_mm: NDArray[np.float64]
    from_twin: NDArray[np.float64]


def parabola_slopes(
    surface: NDArray[np.float64], points: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(2, N) dz/dx, dz/dy of z = F + D x + A x^2 + E y + C x y + B y^2 at ``points``."""
    _, d, a, e, c, b = surface
    x, y = points[:, 0], points[:, 1]
    return np.stack([d + 2 * a * x + c * y, e + c * x + 2 * b * y])


def deviation(
    measured: FacetMeasurement,
    design_focal_mm: tuple[float, float],
    twin_screen_mm: NDArray[np.float64] | None,
    twin: FacetMeasurement | None = None,
) -> Deviation:
    """The part's deviation maps; ``twin_screen_mm`` (H, W, 3) the twin's screen points
    in screen coordinates, ``twin`` its frames reconstructed (or None: not rendered)."""
    mask = measured.mask
    points = measured.solution.points_mm
    design = np.array(
        [0.0, 0.0, 1 / (4 * design_focal_mm[0]), 0.0, 0.0, 1 / (4 * design_focal_mm[1])]
    )
    out = {}
    for name, surface in (("design", design), ("fit", measured.solution.surface)):
        values = np.full((2, *mask.shape), np.nan)
        values[:, mask] = measured.solution.slopes - parabola_slopes(surface, points)
        out[name] = values
    screen = np.full((2, *mask.shape), np.nan)
    if twin_screen_mm is not None:
        screen[:, mask] = (measured.screen_mm[mask][:, :2] - twin_screen_mm[mask][:, :2]).T
    from_twin = np.full((2, *mask.shape), np.nan)
    if twin is not None:
        both = mask & twin.mask
        from_twin[:, both] = measured.slopes[:, both] - twin.slopes[:, both]
    return Deviation(
        from_design=out["design"], from_fit=out["fit"], screen_mm=screen, from_twin=from_twin
    )


def twin_screen_points(
    uv_mm: NDArray[np.float64], plane: Any, frames: TwinFrames
) -> NDArray[np.float64]:
    """The twin's exact screen points (H, W, 3) in the station's screen coordinates, from
    its rendered ``uv_mm`` (H, W, 2) on the emitter ``plane``."""
    points = plane.centre + uv_mm[..., 0:1] * plane.e_u + uv_mm[..., 1:2] * plane.e_v
    return frames.screen_of_part(points.reshape(-1, 3)).reshape(points.shape)


def frames_beside(
    measurement: SofastMeasurement,
    real: SofastDecoded,
    twin: SofastDecoded,
    mask: NDArray[np.bool_],
) -> dict[str, Any]:
    """Per direction (x, y) and period (periods per screen, SOFAST's order): the median
    over ``mask`` of the modulation as a share of white - black, ``real`` (the recorded
    frames decoded) and ``twin`` (the twin's frames decoded alike), their ratio, and the
    real offset's share; the real fit residual's median (counts, and as a share of
    white - black)."""
    span = (measurement.white.astype(float) - measurement.black)[mask]
    out: dict[str, Any] = {}
    for direction in measurement.direction_order:
        periods = measurement.periods_x if direction == "x" else measurement.periods_y
        real_mod, twin_mod, real_off, residual = (
            getattr(decoded, f"{name}_{direction}")
            for decoded, name in (
                (real, "modulation"),
                (twin, "modulation"),
                (real, "offset"),
                (real, "residual"),
            )
        )
        rows = []
        for k, p in enumerate(periods):
            real_share = float(np.median(real_mod[k][mask]))
            twin_share = float(np.median(twin_mod[k][mask]))
            rows.append(
                {
                    "periods_per_screen": float(p),
                    "real_modulation_share": real_share,
                    "twin_modulation_share": twin_share,
                    "real_to_twin": real_share / twin_share,
                    "real_offset_share": float(np.median(real_off[k][mask])),
                }
            )
        out[direction] = {
            "periods": rows,
            "residual_counts_median": float(np.median(residual[mask] * span)),
            "residual_share_median": float(np.median(residual[mask])),
        }
    return out


def rms_mrad(values: NDArray[np.float64]) -> list[float]:
    """The rms (mrad) of each slope map (2, H, W) over its finite pixels."""
    return [float(np.sqrt(np.nanmean(v**2)) * 1e3) for v in values]
