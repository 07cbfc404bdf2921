"""Read a SOFAST (Sandia OpenCSP) fringe measurement and its display-response calibration,
and decode it through glshade's own decoder (:func:`decode_sofast`): SOFAST's conventions
(frame order, periods per screen, the sense of each screen fraction, its image
calibration) are mapped onto glshade's coding, never onto a copy of the decoder
(docs/sofast.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from glshade.capture.response import Response
from glshade.errors import GlshadeError

if TYPE_CHECKING:
    from glshade.capture.model import Capture, CaptureCoding


@dataclass(frozen=True)
class SofastMeasurement:
    """A SOFAST fringe measurement as recorded (lengths in mm)."""

    frames: NDArray[Any]  # (F, H, W), SOFAST's frame order (uint8 as recorded)
    black: NDArray[Any]  # (H, W)
    white: NDArray[Any]  # (H, W)
    periods_y: tuple[float, ...]  # periods per screen, in frame order
    periods_x: tuple[float, ...]
    shifts: int
    direction_order: tuple[str, ...]
    dist_optic_screen_mm: float
    shift_sign: int = 1  # cos(phase - n*2pi/N), start phase 0
    name: str = ""
    date: str = ""
    measure_point_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)  # facet coordinates


@dataclass(frozen=True)
class SofastCalibration:
    """SOFAST's display-response calibration: camera values <-> display values."""

    calibration_type: str
    camera_values: NDArray[np.float64]
    display_values: NDArray[np.float64]

    def as_response(self, source: str = "") -> Response:
        """The record as a display response of kind ``sofast``: applied exactly as
        OpenCSP's ``ImageCalibrationScaling`` applies it."""
        return Response(
            "sofast",
            recorded=self.camera_values,
            commanded=self.display_values,
            source=source or f"SOFAST {self.calibration_type}",
        )

    def response(self, values: NDArray[np.generic]) -> NDArray[np.float64]:
        """OpenCSP's response function: interp1d over strictly increasing camera values,
        clamped to the first/last display value outside."""
        return self.as_response().curve(values)

    def apply(self, measurement: SofastMeasurement) -> NDArray[np.float64]:
        """Frames (F, H, W) calibrated as OpenCSP's ImageCalibrationScaling does (display
        values; the black and white scaled to the display's maximum; 0 where white is
        not above black)."""
        response = self.as_response()
        frames = measurement.frames
        return response.normalised(frames, measurement.black, measurement.white, 1.0)[0]


def _text(value: object) -> str:
    return value.decode() if isinstance(value, bytes) else str(value)


def read_sofast_measurement(path: str | Path) -> SofastMeasurement:
    import h5py

    try:
        with h5py.File(path, "r") as h5:
            g = h5["MeasurementSofastFringe"]
            images = np.asarray(g["fringe_images"][()])  # (H, W, F)
            masks = np.asarray(g["mask_images"][()])  # (H, W, 2)
            periods_x = tuple(float(p) for p in g["fringe_periods_x"][()])
            periods_y = tuple(float(p) for p in g["fringe_periods_y"][()])
            dist_m = float(g["dist_optic_screen"][()])
            name = _text(g["name"][()]) if "name" in g else ""
            date = _text(g["date"][()]) if "date" in g else ""
            point = g["v_measure_point_facet"][()] if "v_measure_point_facet" in g else np.zeros(3)
    except OSError as exc:
        raise GlshadeError(f"{path}: not a readable HDF5 file ({exc})") from None
    except (KeyError, ValueError, TypeError) as exc:
        raise GlshadeError(
            f"{path}: not an OpenCSP SOFAST fringe measurement (MeasurementSofastFringe: {exc})"
        ) from None
    n_periods = len(periods_x) + len(periods_y)
    if (
        images.ndim != 3
        or masks.shape != (*images.shape[:2], 2)
        or images.shape[2] % max(n_periods, 1)
    ):
        raise GlshadeError(
            f"{path}: fringe_images {images.shape} and mask_images {masks.shape} do not fit "
            f"{n_periods} periods"
        )
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
        name=name,
        date=date,
        measure_point_mm=tuple(float(v) * 1000.0 for v in np.ravel(point)[:3]),  # type: ignore[arg-type]
    )


def sofast_bytes(measurement: SofastMeasurement) -> bytes:
    """The measurement as an OpenCSP ``MeasurementSofastFringe`` HDF5 file (metres, uint8
    frames (H, W, F), masks (H, W, 2)): what :func:`read_sofast_measurement` reads back
    the same, array for array."""
    import io

    import h5py

    frames = np.asarray(measurement.frames)
    for what, image in (
        ("frames", frames),
        ("black", measurement.black),
        ("white", measurement.white),
    ):
        values = np.asarray(image, np.float64)
        if not np.array_equal(values, np.clip(np.round(values), 0, 255)):
            raise GlshadeError(f"SOFAST file: the {what} must be whole values 0 to 255 (uint8)")
    buffer = io.BytesIO()
    with h5py.File(buffer, "w") as h5:
        g = h5.create_group("MeasurementSofastFringe")
        g["date"] = measurement.date
        g["dist_optic_screen"] = measurement.dist_optic_screen_mm / 1000.0
        g["fringe_images"] = np.moveaxis(frames.astype(np.uint8), 0, -1)
        g["fringe_periods_x"] = np.asarray(measurement.periods_x, np.float64)
        g["fringe_periods_y"] = np.asarray(measurement.periods_y, np.float64)
        masks = np.stack([measurement.black, measurement.white], axis=-1)
        g["mask_images"] = masks.astype(np.uint8)
        g["name"] = measurement.name
        g["v_measure_point_facet"] = np.asarray(measurement.measure_point_mm, np.float64) / 1000.0
    return buffer.getvalue()


def write_sofast_measurement(path: str | Path, measurement: SofastMeasurement) -> None:
    """Write :func:`sofast_bytes` to ``path``, atomically."""
    from glshade.files import atomic_write_bytes

    atomic_write_bytes(Path(path), sofast_bytes(measurement))


def measurement_of(capture: Capture, dist_optic_screen_mm: float) -> SofastMeasurement:
    """A capture in SOFAST's conventions (:func:`sofast_coding`: y then x, periods per
    screen, direction, period, shift; sign +1; x from the low edge, y from the high;
    black and white references) as a SOFAST measurement; one line where it is not."""
    coding = capture.coding
    wrong = GlshadeError(
        f"{capture.source or 'capture'}: not in SOFAST's conventions (periods per screen; "
        "direction, period, shift; sign +1; x from its low edge, y from its high; black "
        "and white references)"
    )
    if capture.black is None or capture.white is None:
        raise wrong
    measurement = SofastMeasurement(
        frames=np.asarray(capture.frames),
        black=np.asarray(capture.black),
        white=np.asarray(capture.white),
        periods_y=coding.periods,
        periods_x=coding.periods,
        shifts=coding.shifts,
        direction_order=tuple("x" if d == "u" else "y" for d in coding.directions),
        dist_optic_screen_mm=dist_optic_screen_mm,
    )
    if coding.to_dict() != sofast_coding(measurement, coding.screen_size_mm).to_dict():
        raise wrong
    return measurement


def read_sofast_calibration(path: str | Path) -> SofastCalibration:
    import h5py

    try:
        with h5py.File(path, "r") as h5:
            g = h5["ImageCalibration"]
            return SofastCalibration(
                calibration_type=_text(g["calibration_type"][()]),
                camera_values=np.asarray(g["camera_values"][()], dtype=np.float64),
                display_values=np.asarray(g["display_values"][()], dtype=np.float64),
            )
    except OSError as exc:
        raise GlshadeError(f"{path}: not a readable HDF5 file ({exc})") from None
    except (KeyError, ValueError, TypeError) as exc:
        raise GlshadeError(f"{path}: not an OpenCSP image calibration ({exc})") from None


EXTENT_MM = 1000.0


def sofast_coding(
    measurement: SofastMeasurement, screen_size_mm: tuple[float, float] = (EXTENT_MM, EXTENT_MM)
) -> CaptureCoding:
    """SOFAST's sequence in a capture's terms: y (glshade's v) then x (u), periods per
    screen in frame order, the shifts innermost; SOFAST's x fraction runs with the screen
    coordinate glshade decodes (origin low), its y fraction against it (origin high);
    phase steps of +2π n / N."""
    from glshade.capture.model import CaptureCoding

    if measurement.periods_x != measurement.periods_y:
        raise GlshadeError("SOFAST measurement: x and y periods differ; glshade reads one list")
    return CaptureCoding(
        directions=tuple("u" if d == "x" else "v" for d in measurement.direction_order),
        periods=measurement.periods_x,
        period_unit="screen",
        order=("direction", "period", "shift"),
        shifts=measurement.shifts,
        shift_sign=measurement.shift_sign,
        origin=("low", "high"),
        screen_size_mm=screen_size_mm,
    )


def sofast_capture(
    measurement: SofastMeasurement,
    screen_size_mm: tuple[float, float] = (EXTENT_MM, EXTENT_MM),
    source: str = "",
    response: Response | SofastCalibration | None = None,
) -> Capture:
    """The measurement as a :class:`~glshade.capture.model.Capture` (frames as recorded,
    black and white from its mask images, :func:`sofast_coding`); ``screen_size_mm`` the
    screen's extent (the fractions do not depend on it; its mm do), a nominal 1 m square
    by default; ``response`` the station's display response (a SOFAST calibration record
    is applied as OpenCSP applies it)."""
    from glshade.capture.model import Capture

    if isinstance(response, SofastCalibration):
        response = response.as_response()
    return Capture(
        measurement.frames,
        sofast_coding(measurement, screen_size_mm),
        black=measurement.black,
        white=measurement.white,
        source=source or "SOFAST measurement",
        response=response,
        extra={"sofast": measurement},
    )


def read_sofast_capture(
    path: str | Path,
    response: Response | SofastCalibration | str | Path | None = None,
    screen_size_mm: tuple[float, float] = (EXTENT_MM, EXTENT_MM),
) -> Capture:
    """A SOFAST measurement file read as a capture; ``response`` its display response: a
    :class:`Response`, a calibration record, or the path of an OpenCSP
    ``image_calibration.h5`` (None: none)."""
    if isinstance(response, str | Path):
        response = read_sofast_calibration(response).as_response(str(response))
    return sofast_capture(read_sofast_measurement(path), screen_size_mm, str(path), response)


@dataclass(frozen=True)
class SofastDecoded:
    """Screen fractions in SOFAST's convention, per pixel (H, W), and what the decoder
    says of them: ``valid``; ``modulation_x``, ``modulation_y``, ``offset_x``,
    ``offset_y`` (K, H, W) in SOFAST's period order (shares of white - black);
    ``residual_x``, ``residual_y`` the N-step fit's rms residual over every period
    (shares of white - black); ``decoding`` all of glshade's maps."""

    x: NDArray[np.float64]
    y: NDArray[np.float64]
    valid: NDArray[np.bool_]
    modulation_x: NDArray[np.float64]
    modulation_y: NDArray[np.float64]
    residual_x: NDArray[np.float64]
    residual_y: NDArray[np.float64]
    offset_x: NDArray[np.float64]
    offset_y: NDArray[np.float64]
    decoding: Any = None


def decode_sofast(
    measurement: SofastMeasurement,
    calibration: SofastCalibration | None = None,
    rule: str = "all",
) -> SofastDecoded:
    """Decode through :func:`glshade.capture.decode.decode_capture` (one decoder): the
    measurement as a capture (:func:`sofast_capture`), the calibration record as its
    display response (applied as OpenCSP applies it), no mask (the caller locates the
    facet); ``rule`` as :data:`glshade.capture.decode.RULES`. Modulation and residual
    as shares of white - black."""
    from glshade.capture.decode import DecodeSettings, decode_capture

    capture = sofast_capture(measurement, response=calibration)
    decoded = decode_capture(capture, settings=DecodeSettings(rule=rule, mask="all"))
    order = np.argsort(np.argsort(measurement.periods_x)[::-1])  # finest first -> SOFAST's
    share = 1.0 / decoded.peak
    return SofastDecoded(
        x=decoded.fraction[..., 0],
        y=decoded.fraction[..., 1],
        valid=decoded.valid,
        modulation_x=decoded.modulation[0][order] * share,
        modulation_y=decoded.modulation[1][order] * share,
        residual_x=decoded.residual[0] * share,
        residual_y=decoded.residual[1] * share,
        offset_x=decoded.offset[0][order] * share,
        offset_y=decoded.offset[1][order] * share,
        decoding=decoded,
    )
