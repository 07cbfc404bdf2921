"""What a real screen shows for a commanded value: its grey levels, its response (a gamma
or a measured curve read from a file), its black level and the room light its face
reflects; and the cosine series of a displayed fringe (what a lobe's closed form and the
screen's diffuse reflection are computed from).

A commanded value ``c`` in [0, 1] is rounded to the nearest of ``levels`` grey levels
(halves up; ``levels = 0``: not rounded), taken through the response ``R`` (``R(0) = 0``,
``R(1) = 1``: ``c ** gamma``, or the measured curve) and shown above the black level:

    displayed(c) = ambient + black + (1 - black) R(quantised c)

in units of the screen's white above its black (1 at ``c = 1`` without ambient light and
black level). The float64 oracle of the shader's ``fringe_displayed``.
"""

from __future__ import annotations

import functools
import math
import os
from dataclasses import dataclass, field

import numpy as np

from glshade.errors import SceneError
from glshade.files import note_input, read_regular_text

#: Samples of a measured response curve as the renderer holds it: the file's piecewise-
#: linear curve taken at this many evenly spaced commanded values (the shader and the
#: oracle interpolate the same table linearly; the resampling moves a value by at most the
#: curve's change of slope over 1/4095 of full scale).
RESPONSE_SAMPLES = 4096
#: The most points a response file may hold, and its size limit.
MAX_RESPONSE_POINTS = 65536
MAX_RESPONSE_BYTES = 4 << 20
#: The largest magnitude a normalised response may reach (a curve that rises 1000 times its
#: white above it is not a screen's).
MAX_RESPONSE_RATIO = 1000.0
#: Harmonics of a displayed fringe the shader keeps (b_0 to b_7): beyond the 7th a
#: quantised, gamma-curved fringe holds a fraction of a grey level.
HARMONICS = 8
#: Phase samples of one period when its cosine series is computed.
_SERIES_SAMPLES = 4096


@dataclass(frozen=True)
class ResponseCurve:
    """A measured response: ``table`` (:data:`RESPONSE_SAMPLES` values of ``R`` at evenly
    spaced commanded values, ``R(0) = 0``, ``R(1) = 1``, float64) read from ``source``."""

    source: str
    table: np.ndarray = field(repr=False, compare=False)

    @functools.cached_property
    def texture(self) -> np.ndarray:
        """The table as the shader reads it: a (1, N) float32 texture, one array for the
        curve's life (the renderer uploads an array once)."""
        return self.table.astype(np.float32).reshape(1, -1)

    def __call__(self, commanded: np.ndarray) -> np.ndarray:
        grid = np.linspace(0.0, 1.0, len(self.table))
        return np.interp(commanded, grid, self.table)


def read_response(path: str) -> ResponseCurve:
    """The response curve in ``path`` (kept while the file is unchanged): a text file of
    ``commanded, displayed`` pairs, one a line (commas, tabs or spaces; ``#`` starts a
    comment). Commanded values increase from 0 to their full scale (1, 255, 1023, …: the
    last one), displayed values are the screen's measured output in any unit; the response
    is ``(L - L(0)) / (L(full) - L(0))`` (the black level is ``emitter.black_level``)."""
    note_input(path)  # a file this run reads: never one of its outputs
    try:
        stat = os.stat(path)
    except OSError:
        stat = None
    key = (stat.st_mtime_ns, stat.st_size) if stat is not None else None
    return _read_response(path, key)


@functools.lru_cache(maxsize=4)
def _read_response(path: str, key: object) -> ResponseCurve:
    text = read_regular_text(path, "emitter.response_file", MAX_RESPONSE_BYTES)
    rows = []
    for number, line in enumerate(text.splitlines(), 1):
        line = line.partition("#")[0].replace(",", " ").replace("\t", " ").strip()
        if not line:
            continue
        parts = line.split()
        try:
            values = [float(part) for part in parts]
        except ValueError:
            values = []
        if len(values) != 2 or not all(math.isfinite(v) for v in values):
            raise SceneError(
                "emitter.response_file",
                f"two finite numbers a line (commanded, displayed); line {number} of {path} is",
                line[:60],
            )
        rows.append(values)
        if len(rows) > MAX_RESPONSE_POINTS:
            raise SceneError(
                "emitter.response_file", f"at most {MAX_RESPONSE_POINTS} points", f"{path}"
            )
    return ResponseCurve(path, _normalised(path, np.array(rows, np.float64).reshape(-1, 2)))


def _normalised(path: str, rows: np.ndarray) -> np.ndarray:
    """The curve's points as :data:`RESPONSE_SAMPLES` values of ``R`` on [0, 1]."""
    name = os.path.basename(path)
    commanded, displayed = rows[:, 0], rows[:, 1]
    if len(rows) < 2 or commanded[0] != 0.0 or np.any(np.diff(commanded) <= 0.0):
        raise SceneError(
            "emitter.response_file",
            "at least two points whose commanded values increase from 0",
            name,
        )
    with np.errstate(over="ignore"):
        span = displayed[-1] - displayed[0]
    if not (span > 0.0 and math.isfinite(span)):
        raise SceneError(
            "emitter.response_file",
            "a curve whose full scale displays more than its 0 (displayed[-1] > displayed[0])",
            name,
        )
    grid = np.linspace(0.0, 1.0, RESPONSE_SAMPLES)
    with np.errstate(over="ignore", invalid="ignore"):
        table = np.interp(grid, commanded / commanded[-1], (displayed - displayed[0]) / span)
    if not np.all(np.isfinite(table)) or np.abs(table).max() > MAX_RESPONSE_RATIO:
        raise SceneError(
            "emitter.response_file",
            f"a curve whose displayed values stay within {MAX_RESPONSE_RATIO:g} times its "
            "range (L(full) - L(0))",
            name,
        )
    return table


@dataclass(frozen=True)
class ScreenResponse:
    """How a screen turns commanded values into radiance: ``levels`` (0: continuous),
    ``gamma`` or ``curve`` (a measured response), ``black`` (its radiance at black over its
    white) and ``ambient`` (the room light its face reflects, same units)."""

    levels: int = 0
    gamma: float = 1.0
    curve: ResponseCurve | None = None
    black: float = 0.0
    ambient: float = 0.0

    @property
    def floor(self) -> float:
        """The radiance at commanded 0: ambient plus black level."""
        return self.ambient + self.black

    @property
    def gain(self) -> float:
        """The white's radiance above the black level: ``1 - black``."""
        return 1.0 - self.black

    def quantised(self, commanded: np.ndarray) -> np.ndarray:
        """Clamped to [0, 1] and rounded to the nearest grey level (halves up)."""
        c = np.clip(np.asarray(commanded, np.float64), 0.0, 1.0)
        if self.levels:
            c = np.floor(c * (self.levels - 1) + 0.5) / (self.levels - 1)
        return c

    def response(self, commanded: np.ndarray) -> np.ndarray:
        """``R`` of (already quantised) commanded values."""
        if self.curve is not None:
            return self.curve(commanded)
        return np.asarray(commanded, np.float64) ** self.gamma

    def displayed(self, commanded: np.ndarray) -> np.ndarray:
        """The radiance shown for commanded values (float64; NaN propagates)."""
        return self.floor + self.gain * self.response(self.quantised(commanded))

    def harmonics(self, offset: float, amplitude: float, count: int = HARMONICS) -> np.ndarray:
        """``b_0 … b_{count-1}``: the cosine series of the fringe ``θ ↦ displayed(offset +
        amplitude cos θ)`` (an even function of θ), by the FFT of one period."""
        theta = 2.0 * math.pi * np.arange(_SERIES_SAMPLES) / _SERIES_SAMPLES
        values = self.displayed(offset + amplitude * np.cos(theta))
        spectrum = np.fft.rfft(values) / _SERIES_SAMPLES
        series = np.zeros(count)
        series[0] = spectrum[0].real
        series[1:] = 2.0 * spectrum[1:count].real
        return series
