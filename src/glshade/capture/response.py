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
