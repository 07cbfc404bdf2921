"""A station's display response: what a recorded value says of the value the screen was
commanded to show (docs/captures.md). A phase-shifting decoder needs the commanded
sinusoid; a screen with a gamma, or a camera that is not linear, records a distorted one
whose harmonics bias the phase. The response undoes it before black and white
normalise the frames.

- ``gamma``: the screen shows ``c^γ`` of its range for a command ``c`` in [0, 1]; the
  recorded ``(I - black) / (white - black)`` is raised to ``1/γ``.
- ``curve``: measured pairs (recorded value, commanded value), increasing; interpolated
  linearly, clamped beyond its ends; recorded values, black and white all go through it,
  then the frames are normalised (OpenCSP's ``ImageCalibrationScaling``, whose record
  glshade reads, is this).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from glshade.errors import GlshadeError

KINDS = ("gamma", "curve")


@dataclass(frozen=True)
class Response:
    """``kind`` gamma or curve; ``gamma`` the exponent; ``recorded``, ``commanded`` the
    curve's pairs (strictly increasing recorded values); ``source`` where it came from."""

    kind: str
    gamma: float = 1.0
    recorded: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    commanded: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    source: str = ""

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise GlshadeError(f"response kind {self.kind!r}: one of {', '.join(KINDS)}")
        if self.kind == "gamma" and not (math.isfinite(self.gamma) and self.gamma > 0):
            raise GlshadeError(f"gamma {self.gamma}: a finite number above 0")
        if self.kind == "curve":
            rec, com = np.asarray(self.recorded, float), np.asarray(self.commanded, float)
            if rec.ndim != 1 or rec.shape != com.shape or rec.size < 2:
                raise GlshadeError(f"{self.source or 'response curve'}: at least 2 pairs needed")
            if not (np.all(np.isfinite(rec)) and np.all(np.isfinite(com))):
                raise GlshadeError(f"{self.source or 'response curve'}: values must be finite")

    @property
    def label(self) -> str:
        """A short name: ``gamma 2.2`` or ``curve (FILE)``."""
        if self.kind == "gamma":
            return f"gamma {self.gamma:g}"
        return f"curve ({self.source})" if self.source else "curve"

    def curve(self, values: NDArray[np.generic]) -> NDArray[np.float64]:
        """The commanded value of recorded ``values`` through the curve: linear between
        its points where the recorded values increase (a pair that does not increase on
        its predecessor is skipped, as OpenCSP skips it), its first (last) commanded
        value below (above) them."""
        rec, com = np.asarray(self.recorded, float), np.asarray(self.commanded, float)
        keep = np.ones(rec.size, bool)
        keep[np.where(np.diff(rec) <= 0)[0]] = False
        x = np.asarray(values, np.float64)
        out = np.interp(x, rec[keep], com[keep])
        out[x < rec[keep][0]] = com[0]
        out[x > rec[keep][-1]] = com[-1]
        return out

    def normalised(
        self,
        frames: NDArray[np.generic],
        black: NDArray[np.generic] | None,
        white: NDArray[np.generic] | None,
        peak: float,
    ) -> tuple[NDArray[np.float64], bool]:
        """The frames as shares of the commanded range (0 black, 1 white), NaN where white
        is not above black; ``peak`` the recorded white above black where the references
        are missing. Also whether black and white were used."""
        if self.kind == "curve":
            values = self.curve(frames)
            if black is not None and white is not None:
                low, high = self.curve(black), self.curve(white)
                return _share(values, low, high), True
            return values / float(np.max(self.commanded)), False
        if black is not None and white is not None:
            share = _share(np.asarray(frames, np.float64), np.asarray(black, float), white)
            used = True
        else:
            share, used = np.asarray(frames, np.float64) / peak, False
        with np.errstate(invalid="ignore"):
            return np.maximum(share, 0.0) ** (1.0 / self.gamma), used


def _share(
    values: NDArray[np.float64], low: NDArray[np.generic], high: NDArray[np.generic]
) -> NDArray[np.float64]:
    base = np.asarray(low, np.float64)
    span = np.asarray(high, np.float64) - base
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.asarray((values - base) * np.where(span > 0, 1.0 / span, np.nan), np.float64)


def parse_response(text: str) -> Response:
    """``gamma:G``, or a file: ``.csv`` (two columns: recorded, commanded; a header line
    allowed), ``.toml`` (``recorded = [...]``, ``commanded = [...]``) or an OpenCSP
    ``image_calibration.h5``."""
    if text.startswith("gamma:"):
        try:
            gamma = float(text[len("gamma:") :])
        except ValueError:
            raise GlshadeError(f"--response {text}: gamma:G with G a number above 0") from None
        return Response("gamma", gamma=gamma, source=text)
    path = Path(text)
    if not path.is_file():
        raise GlshadeError(
            f"--response {text}: no such file (gamma:G, or a .csv, .toml or OpenCSP .h5 curve)"
        )
    suffix = path.suffix.lower()
    if suffix in (".h5", ".hdf5"):
        from glshade.capture.sofast import read_sofast_calibration

        record = read_sofast_calibration(path)
        return Response(
            "curve",
            recorded=record.camera_values,
            commanded=record.display_values,
            source=str(path),
        )
    if suffix == ".csv":
        return _csv_response(path)
    if suffix == ".toml":
        return _toml_response(path)
    raise GlshadeError(f"--response {text}: a .csv, .toml or .h5 file, or gamma:G")


def _csv_response(path: Path) -> Response:
    rows = []
    for number, line in enumerate(path.read_text().splitlines(), 1):
        cells = [c.strip() for c in line.replace(";", ",").split(",") if c.strip()]
        if not cells:
            continue
        try:
            rows.append((float(cells[0]), float(cells[1])))
        except (ValueError, IndexError):
            if number == 1:
                continue  # a header
            raise GlshadeError(
                f"{path}:{number}: two numbers (recorded, commanded), got {line!r}"
            ) from None
    pairs = np.array(rows, float).reshape(-1, 2)
    return Response("curve", recorded=pairs[:, 0], commanded=pairs[:, 1], source=str(path))


def _toml_response(path: Path) -> Response:
    from glshade.scene.model import read_toml

    data = read_toml(path, "response curve")
    try:
        recorded = np.asarray(data["recorded"], float)
        commanded = np.asarray(data["commanded"], float)
    except (KeyError, ValueError, TypeError):
        raise GlshadeError(
            f"{path}: needs recorded = [numbers] and commanded = [numbers]"
        ) from None
    return Response("curve", recorded=recorded, commanded=commanded, source=str(path))
