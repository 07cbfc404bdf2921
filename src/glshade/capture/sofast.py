"""Read a SOFAST (Sandia OpenCSP) fringe measurement and its display-response calibration,
and decode it through glshade's own decoder (:func:`decode_sofast`): SOFAST's conventions
(frame order, periods per screen, the sense of each screen fraction, its image
calibration) are mapped onto glshade's coding, never onto a copy of the decoder
(docs/sofast.md).
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
    sense: tuple[int, int] = (1, -1)  # (x, y): SOFAST fraction = s/E or 1 - s/E
    shift_sign: int = 1  # cos(phase - n*2pi/N), start phase 0


@dataclass(frozen=True)
class SofastCalibration:
    """SOFAST's display-response calibration: camera values <-> display values."""

    calibration_type: str
    camera_values: NDArray[np.float64]
    display_values: NDArray[np.float64]

    def response(self, values: NDArray[np.generic]) -> NDArray[np.float64]:
        """OpenCSP's response function: interp1d over strictly increasing camera values,
        clamped to the first/last display value outside."""
        cam, disp = self.camera_values, self.display_values
        keep = np.ones(cam.size, dtype=bool)
        keep[np.where(np.diff(cam) <= 0)[0]] = False
        x = np.asarray(values, dtype=np.float64)
        out = np.interp(x, cam[keep], disp[keep])
        out[x < cam[keep][0]] = disp[0]
        out[x > cam[keep][-1]] = disp[-1]
        return out

    def apply(self, measurement: SofastMeasurement) -> NDArray[np.float64]:
        """Frames (F, H, W) calibrated as OpenCSP's ImageCalibrationScaling does."""
        dark = self.response(measurement.black)[None]
        light = self.response(measurement.white)[None]
        frames = self.response(measurement.frames)
        delta = light - dark
        delta[delta <= 0] = np.nan
        scaled = (frames - dark) * (float(self.display_values[-1]) / delta)
        scaled[np.isnan(scaled)] = 0.0
        return scaled


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


EXTENT_MM = 1000.0


@dataclass(frozen=True)
class SofastDecoded:
    """Screen fractions in SOFAST's convention, per pixel (H, W)."""

    x: NDArray[np.float64]
    y: NDArray[np.float64]
    valid: NDArray[np.bool_]
    modulation_x: NDArray[np.float64]  # (K, H, W), SOFAST's period order
    modulation_y: NDArray[np.float64]
    residual_x: NDArray[np.float64]  # rms of frames minus A + B cos(phi - delta_n), all periods
    residual_y: NDArray[np.float64]


def _residual(frames: NDArray[np.float64], shifts: int) -> NDArray[np.float64]:
    """frames (K, N, H, W): rms over K, N of the N-step least-squares fit residual."""
    delta = 2.0 * np.pi * np.arange(shifts) / shifts
    c = np.cos(delta)[None, :, None, None]
    s = np.sin(delta)[None, :, None, None]
    a = frames.mean(axis=1, keepdims=True)
    bc = (2.0 / shifts) * (frames * c).sum(axis=1, keepdims=True)
    bs = (2.0 / shifts) * (frames * s).sum(axis=1, keepdims=True)
    fit = a + bc * c + bs * s
    return np.sqrt(((frames - fit) ** 2).mean(axis=(0, 1)))


def decode_sofast(
    measurement: SofastMeasurement, calibration: SofastCalibration | None = None
) -> SofastDecoded:
    """Decode with glshade's decoder. SOFAST shows cos(2 pi p (1 - f) - n pi/2) for p
    periods per screen: glshade's s = EXTENT (1 - f) on periods EXTENT / p mm, finest first."""
    from glshade.components.emitter.fringes.codec import FringeCodec
    from glshade.instruments.pmd.decode import decode

    if calibration is not None:
        frames = calibration.apply(measurement)
        peak = float(calibration.display_values[-1])
    else:
        frames = measurement.frames.astype(np.float64)
        peak = 255.0
    n = measurement.shifts
    out: dict[
        str, tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.float64], NDArray[np.float64]]
    ]
    out = {}
    start = 0
    for direction in measurement.direction_order:
        periods = measurement.periods_y if direction == "y" else measurement.periods_x
        k = len(periods)
        block = frames[start : start + k * n].reshape(k, n, *frames.shape[1:])
        start += k * n
        order = np.argsort(periods)[::-1]  # most periods per screen = finest first
        codec = FringeCodec(
            periods_mm=tuple(EXTENT_MM / periods[i] for i in order),
            shifts=n,
            directions=("u", "v"),
            screen_half_size_mm=(EXTENT_MM / 2.0, EXTENT_MM / 2.0),
        )
        dec = decode(
            block[order], codec, peak_response=peak, direction="u" if direction == "x" else "v"
        )
        s_frac = np.asarray(dec.s_mm, dtype=np.float64) / EXTENT_MM
        # measured against expected_facet.h5: x runs with s, y against it
        frac = s_frac if direction == "x" else 1.0 - s_frac
        mod = np.asarray(dec.modulation)[np.argsort(order)]
        out[direction] = (frac, np.asarray(dec.valid), mod, _residual(block, n))
    return SofastDecoded(
        x=out["x"][0],
        y=out["y"][0],
        valid=out["x"][1] & out["y"][1],
        modulation_x=out["x"][2],
        modulation_y=out["y"][2],
        residual_x=out["x"][3],
        residual_y=out["y"][3],
    )
