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


def modulation_offset(
    block: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per period: the N-step fit's modulation and offset (K, H, W) of ``block`` (K, N,
    H, W), shifts evenly spread."""
    shifts = block.shape[1]
    delta = 2 * np.pi * np.arange(shifts) / shifts
    c = (block * np.cos(delta)[None, :, None, None]).sum(1)
    s = (block * np.sin(delta)[None, :, None, None]).sum(1)
    return 2 / shifts * np.hypot(c, s), block.mean(axis=1)


def frames_beside(
    measurement: SofastMeasurement,
    decoded: SofastDecoded,
    mask: NDArray[np.bool_],
    twin: dict[str, NDArray[np.float64]],
    twin_white: NDArray[np.float64],
) -> dict[str, Any]:
    """Per direction (x, y) and period (periods per screen, SOFAST's order): the median
    over ``mask`` of the modulation relative to the white - black span, real and twin,
    and the real offset's; the real fit residual's median (counts, and as a share of
    white - black, the decoded frames' unit). ``twin`` maps a direction to its (K, N, H,
    W) radiance, SOFAST's period order."""
    span_real = (measurement.white.astype(float) - measurement.black)[mask]
    out: dict[str, Any] = {}
    frames = measurement.frames.astype(np.float64)
    start = 0
    for direction in measurement.direction_order:
        periods = measurement.periods_x if direction == "x" else measurement.periods_y
        block = frames[start : start + len(periods) * measurement.shifts]
        start += len(periods) * measurement.shifts
        block = block.reshape(len(periods), measurement.shifts, *frames.shape[1:])
        real_mod, real_off = modulation_offset(block)
        twin_mod, _ = modulation_offset(twin[direction])
        residual = decoded.residual_x if direction == "x" else decoded.residual_y
        rows = []
        for k, p in enumerate(periods):
            rows.append(
                {
                    "periods_per_screen": float(p),
                    "real_modulation_share": float(np.median(real_mod[k][mask] / span_real)),
                    "twin_modulation_share": float(np.median(twin_mod[k][mask] / twin_white[mask])),
                    "real_to_twin": float(
                        np.median(real_mod[k][mask] / span_real)
                        / np.median(twin_mod[k][mask] / twin_white[mask])
                    ),
                    "real_offset_share": float(
                        np.median((real_off[k][mask] - measurement.black[mask]) / span_real)
                    ),
                }
            )
        out[direction] = {
            "periods": rows,
            "residual_counts_median": float(np.median(residual[mask] * span_real)),
            "residual_share_median": float(np.median(residual[mask])),
        }
    return out


def rms_mrad(values: NDArray[np.float64]) -> list[float]:
    """The rms (mrad) of each slope map (2, H, W) over its finite pixels."""
    return [float(np.sqrt(np.nanmean(v**2)) * 1e3) for v in values]
