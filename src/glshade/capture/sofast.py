"""Read a SOFAST (Sandia OpenCSP) fringe measurement and its display-response calibration.

First slice: readers only. Decoding through glshade's decoder is not yet here
(see docs/sofast.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class SofastMeasurement:
    """A SOFAST fringe measurement as recorded (lengths in mm)."""

    frames: NDArray[np.uint8]  # (F, H, W), SOFAST's frame order
    black: NDArray[np.uint8]  # (H, W)
    white: NDArray[np.uint8]  # (H, W)
    periods_y: tuple[float, ...]  # periods per screen, in frame order
    periods_x: tuple[float, ...]
    shifts: int
    direction_order: tuple[str, ...]
    dist_optic_screen_mm: float


@dataclass(frozen=True)
class SofastCalibration:
    """SOFAST's display-response calibration: camera values <-> display values."""

    calibration_type: str
    camera_values: NDArray[np.float64]
    display_values: NDArray[np.float64]

    def apply(self, frames: NDArray[np.generic]) -> NDArray[np.float64]:
        """Map camera values to display values by linear interpolation (unverified vs OpenCSP)."""
        return np.interp(
            np.asarray(frames, dtype=np.float64), self.camera_values, self.display_values
        )


def _text(value: object) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


def read_sofast_measurement(path: str | Path) -> SofastMeasurement:
    import h5py

    with h5py.File(path, "r") as h5:
        g = h5["MeasurementSofastFringe"]
        images = np.asarray(g["fringe_images"][()], dtype=np.uint8)  # (H, W, F)
        masks = np.asarray(g["mask_images"][()], dtype=np.uint8)  # (H, W, 2)
        periods_x = tuple(float(p) for p in g["fringe_periods_x"][()])
        periods_y = tuple(float(p) for p in g["fringe_periods_y"][()])
        dist_m = float(g["dist_optic_screen"][()])
    n_periods = len(periods_x) + len(periods_y)
    frames = np.ascontiguousarray(np.moveaxis(images, -1, 0))
    return SofastMeasurement(
        frames=frames,
        black=np.ascontiguousarray(masks[..., 0]),
        white=np.ascontiguousarray(masks[..., 1]),
        periods_y=periods_y,
        periods_x=periods_x,
        shifts=frames.shape[0] // n_periods,
        direction_order=("y", "x"),
        dist_optic_screen_mm=dist_m * 1000.0,
    )


def read_sofast_calibration(path: str | Path) -> SofastCalibration:
    import h5py

    with h5py.File(path, "r") as h5:
        g = h5["ImageCalibration"]
        return SofastCalibration(
            calibration_type=_text(g["calibration_type"][()]),
            camera_values=np.asarray(g["camera_values"][()], dtype=np.float64),
            display_values=np.asarray(g["display_values"][()], dtype=np.float64),
        )
