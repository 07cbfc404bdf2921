"""The camera's noise, where it is known, and the decoded coordinate's noise it predicts
(docs/captures.md): ``σ_I² = read² + gain · (I - black) + q² / 12`` in recorded units
(photon transfer: read noise, the signal's shot noise through the gain, the
quantisation), and ``σ_s = p / 2π · sqrt(2 / N) · σ_I / B`` for the finest period used.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from glshade.errors import GlshadeError


@dataclass(frozen=True)
class CameraNoise:
    """``read`` the read noise and ``quantum`` the quantisation step (recorded units),
    ``gain`` recorded units per electron (0: shot noise not known); ``black`` the black
    level the recorded values hold (used where the capture has no black reference);
    ``source`` where the numbers came from."""

    read: float
    gain: float
    quantum: float
    source: str
    black: float = 0.0

    def sigma(self, above_black: NDArray[np.generic]) -> NDArray[np.float64]:
        """The intensity noise (recorded units) at a level ``above_black``."""
        level = np.maximum(np.asarray(above_black, np.float64), 0.0)
        return np.sqrt(self.read**2 + self.gain * level + self.quantum**2 / 12.0)


def noise_of_scene(scene: Any) -> CameraNoise | None:
    """A glshade scene's sensor as a :class:`CameraNoise` (recorded units, full scale 1),
    or None without a sensor."""
    if scene is None or not scene.active.records(scene):
        return None
    sensor = scene.sensor
    share = (1.0 - sensor.black_level) / float(sensor.full_well_e)
    return CameraNoise(
        read=share * sensor.read_noise_e,
        gain=share,
        quantum=1.0 / sensor.full_scale_dn,
        source="the capture's scene's sensor",
        black=sensor.black_level,
    )


def parse_noise(text: str) -> CameraNoise:
    """``read=R,gain=G[,q=Q]``: read noise R and quantisation step Q (default 1) in the
    frames' recorded units, G recorded units per electron (0 where unknown)."""
    values: dict[str, float] = {}
    for item in text.split(","):
        key, _, number = item.partition("=")
        try:
            values[key.strip()] = float(number)
        except ValueError:
            values = {}
            break
    if set(values) - {"read", "gain", "q"} or not {"read", "gain"} <= set(values):
        raise GlshadeError(f"--noise {text}: read=R,gain=G[,q=Q] (recorded units; G per electron)")
    if not all(math.isfinite(v) and v >= 0 for v in values.values()):
        raise GlshadeError(f"--noise {text}: numbers of at least 0")
    return CameraNoise(values["read"], values["gain"], values.get("q", 1.0), f"--noise {text}")
