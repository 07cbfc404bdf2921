"""A station's display response: what a recorded value says of the value the screen was
commanded to show (docs/captures.md). A phase-shifting decoder needs the commanded
sinusoid; a screen with a gamma, or a camera that is not linear, records a distorted one
whose harmonics bias the phase. The response undoes it before black and white
normalise the frames.

- ``gamma``: the screen shows ``c^γ`` of its range for a command ``c`` in [0, 1]; the
  recorded ``(I - black) / (white - black)`` is raised to ``1/γ``.
- ``measured``: measured pairs (recorded value, commanded value); interpolated linearly
  (monotone between its points: no overshoot), clamped beyond its ends; recorded values,
  black and white all go through it, then ``(d(I) - d(black)) / (d(white) - d(black))``.
- ``sofast``: OpenCSP's ``ImageCalibrationScaling`` record (camera values, display
  values) applied exactly as OpenCSP applies it: the same curve, then
  ``(d(I) - d(black)) × display_max / (d(white) - d(black))``, 0 where white is not
  above black; the frames are in display values (0 to ``display_max``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from glshade.errors import GlshadeError

KINDS = ("gamma", "measured", "sofast")
#: The kinds that are a curve of (recorded, commanded) pairs.
CURVES = ("measured", "sofast")


@dataclass(frozen=True)
class Response:
    """``kind`` (:data:`KINDS`); ``gamma`` the exponent; ``recorded``, ``commanded`` a
    curve's pairs (recorded values in the capture's units, commanded values in the
    screen's: shares of its range for ``measured``, display values for ``sofast``);
    ``source`` where it came from (the file for a curve read from one)."""

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
        if self.kind in CURVES:
            rec, com = np.asarray(self.recorded, float), np.asarray(self.commanded, float)
            if rec.ndim != 1 or rec.shape != com.shape or rec.size < 2:
                raise GlshadeError(f"{self.source or 'response curve'}: at least 2 pairs needed")
            if not (np.all(np.isfinite(rec)) and np.all(np.isfinite(com))):
                raise GlshadeError(f"{self.source or 'response curve'}: values must be finite")

    @property
    def label(self) -> str:
        """A short name: ``gamma 2.2``, ``measured (FILE)`` or ``sofast (FILE)``."""
        if self.kind == "gamma":
            return f"gamma {self.gamma:g}"
        return f"{self.kind} ({self.source})" if self.source else self.kind

    @property
    def file(self) -> Path | None:
        """The file a curve was read from (None for a gamma or a curve made in code)."""
        if self.kind == "gamma" or not self.source or not Path(self.source).is_file():
            return None
        return Path(self.source)

    @property
    def display_max(self) -> float:
        """The commanded value of the screen's white: the curve's last (OpenCSP's
        ``display_values[-1]``) for ``sofast``, 1 otherwise."""
        return float(self.commanded[-1]) if self.kind == "sofast" else 1.0

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
    ) -> tuple[NDArray[np.float64], float, bool]:
        """The frames in the screen's commanded values (shares of its range, 0 black, 1
        white; display values 0 to ``display_max`` for ``sofast``), NaN where white is
        not above black (0 for ``sofast``, as OpenCSP); ``peak`` the recorded white above
        black where the references are missing. Also the peak of the values returned
        and whether black and white were used."""
        if self.kind in CURVES:
            return self._through_curve(frames, black, white)
        if black is not None and white is not None:
            share = _share(np.asarray(frames, np.float64), np.asarray(black, float), white)
            used = True
        else:
            share, used = np.asarray(frames, np.float64) / peak, False
        with np.errstate(invalid="ignore"):
            return np.maximum(share, 0.0) ** (1.0 / self.gamma), 1.0, used

    def _through_curve(
        self,
        frames: NDArray[np.generic],
        black: NDArray[np.generic] | None,
        white: NDArray[np.generic] | None,
    ) -> tuple[NDArray[np.float64], float, bool]:
        values = self.curve(frames)
        top = self.display_max
        if black is None or white is None:
            return values / float(np.max(self.commanded)) * top, top, False
        shares = _share(values, self.curve(black), self.curve(white), top)
        if self.kind == "sofast":  # ImageCalibrationScaling.apply_to_images: 0, not NaN
            shares[np.isnan(shares)] = 0.0
        return shares, top, True


def _share(
    values: NDArray[np.float64],
    low: NDArray[np.generic],
    high: NDArray[np.generic],
    top: float = 1.0,
) -> NDArray[np.float64]:
    """``(values - low) × (top / (high - low))``, OpenCSP's order of operations; NaN
    where ``high`` is not above ``low``."""
    base = np.asarray(low, np.float64)
    span = np.asarray(high, np.float64) - base
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.asarray((values - base) * np.where(span > 0, top / span, np.nan), np.float64)
