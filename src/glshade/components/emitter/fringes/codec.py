"""The fringe codec: the one description of a phase-measuring fringe coding, shared by the
screen that shows it (the fringe emitter's uniforms and its float64 oracle), the station
that decodes it (:mod:`glshade.instruments.pmd.decode`) and the frames manifest of ``--frames``.

:class:`FringeCodec` holds the sequence (``periods_mm`` finest first, ``shifts``,
``directions``), the commanded fringe (``offset``, ``amplitude``) and the screen that
displays it (``levels``, ``gamma`` or a measured ``screen_response_file``, its black level,
room light and half size). It is validated once, when it is made: each rule has one
message, naming the scene key a user types (``emitter.amplitude``). Frame ``(d, k, n)``
displays, at ``s`` mm from the screen's edge along ``d``:

    x = s / periods[k] - floor(s / periods[k])                (the fringe's fraction)
    commanded = offset + amplitude cos(2π x - 2π n / shifts)
    displayed = screen(commanded)    (clamped, quantised, through the response)

:func:`displayed_fringe` is the one NumPy implementation of it, the shader's arithmetic in
float64 (``fringes.glsl`` reduces the fraction the same way). A coding whose amplitude is
above its offset is shown (the fringe clips at black) but not decoded:
:meth:`FringeCodec.check_decodable` refuses it where a phase decode is asked for.

Importable without GL.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from glshade.components.emitter.fringes.screen import ScreenResponse, read_response
from glshade.components.emitter.stripes.table import Emitter as StripesTable
from glshade.components.emitter.table import MIN_PERIOD_MM
from glshade.errors import GlshadeError, SceneError
from glshade.params import Control, Param

#: The directions a frame's fringes vary along: ``"v"`` (lines of constant ``v``, like the
#: stripes) and ``"u"`` (crossed).
DIRECTIONS = ("v", "u")
#: The most grey levels a screen may command (16 bits).
MAX_LEVELS = 65536
#: The most phase steps per period.
MAX_SHIFTS = 1024
#: The coarsest period allowed, in screens: this many times the screen's larger extent
#: (2 ``half_size``). A coarser one codes the screen in a millionth of a turn, far below
#: any phase a camera resolves, and past about 1e154 mm its squares overflow.
MAX_PERIOD_SCREENS = 1e6

# ------------------------------------------------------------ the declarations
# The coding's scene parameters, declared once: the emitter's table fields carry these
# declarations, and the codec checks a value it is given directly against them (the same
# rule, the same message).
PERIODS = Param(
    "emitter.periods", "mm", (2.0, 16.0, 128.0, 1024.0),
    "fringe periods, finest first; the coarsest at least the screen's extent "
    "2 half_size along each direction, and at most 1e6 times its larger extent",
    value_type="vector",
)  # fmt: skip
SHIFTS = Param(
    "emitter.shifts", "", 4, "phase steps per period, N >= 3 (step 2π n / N)",
    value_type="integer", lo=3, hi=MAX_SHIFTS, control=Control("shifts", 3, 16, fmt="%d"),
)  # fmt: skip
DIRECTIONS_PARAM = Param(
    "emitter.directions", "", DIRECTIONS,
    'the sequence\'s directions: "v" (fringes of constant v, like the stripes), '
    '"u" (crossed)', value_type="names", choices=DIRECTIONS,
)  # fmt: skip
OFFSET = Param(
    "emitter.offset", "", 0.5, "mean commanded value (offset + amplitude <= 1)",
    lo=0.0, closed=True, control=Control("offset", 0.0, 1.0, fmt="%.3f"),
)  # fmt: skip
AMPLITUDE = Param(
    "emitter.amplitude", "", 0.5, "commanded modulation (offset + amplitude <= 1)",
    lo=0.0, closed=True, control=Control("amplitude", 0.0, 1.0, fmt="%.3f"),
)  # fmt: skip
GAMMA = Param(
    "emitter.gamma", "", 1.0, "the screen's response: displayed = commanded ** gamma",
    lo=0.0, control=Control("gamma", 0.2, 5.0, log=True, fmt="%.2f"),
)  # fmt: skip
LEVELS = Param(
    "emitter.levels", "", 256, "commanded grey levels of the screen (0: continuous; never 1)",
    value_type="integer", lo=0, hi=MAX_LEVELS,
    control=Control("levels", 0, 4096, log=True, fmt="%d"),
)  # fmt: skip
BLACK_LEVEL = Param(
    "emitter.black_level", "", 0.0,
    "the screen's radiance at commanded black over its white (1 / its contrast ratio): "
    "an offset in every frame",
    lo=0.0, hi=0.5, closed=True, control=Control("black level", 0.0, 0.1, fmt="%.4f"),
)  # fmt: skip
AMBIENT = Param(
    "emitter.ambient", "", 0.0,
    "the room light the screen's face reflects, in units of its white: an offset in "
    "every frame, the black matrix included",
    lo=0.0, closed=True, plausible_max=1.0,
    plausible_why="more room light than the screen's own white",
    control=Control("ambient", 0.0, 0.2, fmt="%.4f"),
)  # fmt: skip
RESPONSE_FILE = Param(
    "emitter.response_file", "", None,
    "the screen's measured response instead of a gamma: a text file of commanded, "
    "displayed pairs (commanded from 0 to its full scale; displayed in any unit, taken "
    "as (L - L(0)) / (L(full) - L(0)))",
    value_type="path", role="feature",
)  # fmt: skip
#: The screen's half extents: the stripes' declaration, shared by every emitter on that plane.
HALF_SIZE: Param = StripesTable.declaration("half_size")

#: Each field of :class:`FringeCodec` and the scene parameter it is.
DECLARED: dict[str, Param] = {
    "periods_mm": PERIODS,
    "shifts": SHIFTS,
    "directions": DIRECTIONS_PARAM,
    "offset": OFFSET,
    "amplitude": AMPLITUDE,
    "gamma": GAMMA,
    "levels": LEVELS,
    "screen_half_size_mm": HALF_SIZE,
    "screen_black_level": BLACK_LEVEL,
    "screen_ambient": AMBIENT,
    "screen_response_file": RESPONSE_FILE,
}

#: What the frames manifest says beside the codec's values (:meth:`FringeCodec.to_dict`).
DIRECTIONS_NOTE = (
    "directions are listed, and their frames stored, in the order shown; a frame's "
    "direction v codes the screen coordinate v (fringes of constant v), u codes u. Every "
    "per-direction axis of the --maps files is in the order (u, v)"
)
FORMULA = (
    "x = s / period_mm reduced to [0, 1) (x - floor(x)); commanded = offset + amplitude "
    "cos(2 pi x - shift_rad), shift_rad = 2 pi shift_index / shifts; clamped to [0, 1] and "
    "quantised to levels grey levels (floor(c (levels - 1) + 1/2) / (levels - 1); levels 0: "
    "continuous); displayed = screen_ambient + screen_black_level + (1 - screen_black_level) "
    "R(commanded), R = commanded ** gamma or the measured response of screen_response_file"
)
COORDINATE = (
    "s = the screen coordinate along the frame's direction + screen_half_size_mm of that "
    "coordinate (mm from the screen's edge; u is index 0, v index 1); the decoded screen "
    "point is s - that half size"
)
#: The manifest's text entries, each after the codec value it follows.
_NOTES = {"directions": {"directions_note": DIRECTIONS_NOTE}}
_TRAILER = {"phase": FORMULA, "coordinate": COORDINATE, "units": "lengths in mm, shifts in rad"}


def axis_of(direction: str) -> int:
    """The screen coordinate a direction codes: 0 for ``u``, 1 for ``v``."""
    return DIRECTIONS.index(direction) ^ 1


@dataclass(frozen=True)
class FringeFrame:
    """One frame a fringe screen shows: ``offset + amplitude cos(2π s / period_mm -
    shift_rad)`` along ``direction`` (``"v"`` or ``"u"``), quantised and displayed as every
    frame is. ``period_index`` and ``shift_index`` place it in its sequence (``-1``: a
    frame outside the coding, the uniform white screen of :meth:`FringeCodec.white`)."""

    direction: str
    period_index: int
    shift_index: int
    period_mm: float
    shift_rad: float
    offset: float
    amplitude: float

    @property
    def axis(self) -> int:
        """The screen coordinate it varies along: 0 for ``u``, 1 for ``v``."""
        return axis_of(self.direction)

    @property
    def coded(self) -> bool:
        """A frame of the coding (not the white screen)."""
        return self.period_index >= 0


def displayed_fringe(
    screen: ScreenResponse,
    s_mm: np.ndarray,
    period_mm: float | np.ndarray,
    shift_rad: float | np.ndarray,
    offset: float,
    amplitude: float,
) -> np.ndarray:
    """The fringe ``offset + amplitude cos(2π s / period - shift)`` as ``screen`` displays
    it (float64, arguments broadcast as NumPy arrays, NaN kept), at ``s_mm`` mm from the
    screen's edge: the fraction of the period at ``s`` is reduced to [0, 1) first, as the
    shader reduces it, then the cosine is commanded, clamped, quantised and displayed."""
    x = np.asarray(s_mm, np.float64) / period_mm
    x = x - np.floor(x)
    commanded = offset + amplitude * np.cos(2.0 * math.pi * x - shift_rad)
    return np.asarray(screen.displayed(commanded), np.float64)


@dataclass(frozen=True)
class FringeCodec:
    """A fringe coding and the screen that shows it, validated when made (each value
    against its scene parameter's declaration, then the rules over several values;
    :class:`~glshade.errors.SceneError` naming the ``emitter.`` key, one line).

    ``periods_mm``: finest first, increasing, the coarsest at least the screen's extent
    ``2 screen_half_size_mm`` along each of ``directions`` (one fringe spans it: the
    decoding is unambiguous); ``shifts``: ``N >= 3`` steps ``2π n / N``; ``offset``,
    ``amplitude``: the commanded mean and modulation, ``offset + amplitude <= 1``;
    ``levels`` grey levels (0: continuous, never 1); ``gamma`` or
    ``screen_response_file`` (then gamma 1): the response; ``screen_black_level``,
    ``screen_ambient``: offsets of every frame."""

    periods_mm: tuple[float, ...] = PERIODS.default
    shifts: int = SHIFTS.default
    directions: tuple[str, ...] = DIRECTIONS
    offset: float = OFFSET.default
    amplitude: float = AMPLITUDE.default
    gamma: float = GAMMA.default
    levels: int = LEVELS.default
    screen_half_size_mm: tuple[float, float] = HALF_SIZE.default
    screen_black_level: float = BLACK_LEVEL.default
    screen_ambient: float = AMBIENT.default
    screen_response_file: str | None = None

    def __post_init__(self) -> None:
        for name, declared in DECLARED.items():
            object.__setattr__(self, name, declared.check(getattr(self, name)))
        _check_periods(self)
        if self.levels == 1:
            raise SceneError("emitter.levels", "0 (continuous) or at least 2 grey levels", 1)
        if self.screen_response_file is not None:
            if self.gamma != 1.0:
                raise SceneError(
                    "emitter.gamma",
                    "1 where emitter.response_file gives the screen's measured response (one "
                    "response: a gamma or a curve)",
                    self.gamma,
                )
            read_response(self.screen_response_file)
        if self.offset + self.amplitude > 1.0:
            raise SceneError(
                "emitter.offset",
                f"offset + amplitude <= 1 (the screen's full scale; amplitude is "
                f"{self.amplitude:g})",
                self.offset,
            )

    # ------------------------------------------------------------ making one
    @classmethod
    def of(cls, table: Any) -> FringeCodec:
        """The codec of a fringe emitter's table (its ``periods``, ``shifts``,
        ``directions``, ``offset``, ``amplitude``, ``gamma``, ``levels``, ``half_size``,
        ``black_level``, ``ambient``, ``response_file``)."""
        return cls(**{name: getattr(table, declared.key) for name, declared in DECLARED.items()})

    def to_dict(self) -> dict[str, Any]:
        """The codec as the frames manifest writes it: every value (lists for tuples),
        the directions' note, the formula, the coordinate ``s`` and the units."""
        out: dict[str, Any] = {}
        for name in DECLARED:
            value = getattr(self, name)
            out[name] = list(value) if isinstance(value, tuple) else value
            out.update(_NOTES.get(name, {}))
        return {**out, **_TRAILER}

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> FringeCodec:
        """The codec :meth:`to_dict` wrote (its text entries ignored), validated."""
        missing = [name for name in DECLARED if name not in values]
        if missing:
            raise GlshadeError(f"fringe coding: missing {', '.join(missing)}")
        return cls(**{name: values[name] for name in DECLARED})

    # ------------------------------------------------------------ the rules
    def check_decodable(self) -> None:
        """Refuse, in one line, a coding a phase decode cannot read: an amplitude of 0
        (no phase is coded) or above the offset (the commanded fringe goes below black
        and clips there: the frames are no longer ``A + B cos(φ - δ_n)`` and the N-step
        phase is biased). The screen shows either; only a decode is refused."""
        if not 0.0 < self.amplitude <= self.offset:
            raise SceneError(
                "emitter.amplitude",
                f"in (0, emitter.offset = {self.offset:g}] for a phase decode (0 codes no "
                "phase; above the offset the fringe clips at black and biases the phase)",
                self.amplitude,
            )

    # ------------------------------------------------------------ the sequence
    def extent_mm(self, direction: str | None = None) -> float:
        """The screen's length along ``direction`` (``2 screen_half_size_mm``; None: the
        codec's only direction)."""
        if direction is None:
            if len(self.directions) != 1:
                raise GlshadeError(
                    f"fringe coding: name the direction, one of {', '.join(self.directions)}"
                )
            direction = self.directions[0]
        if direction not in DIRECTIONS:
            raise GlshadeError(f"fringe coding: a direction is v or u, got {direction!r}")
        return 2.0 * self.screen_half_size_mm[axis_of(direction)]

    def shift_rad(self, n: int | np.ndarray) -> float | np.ndarray:
        """``δ_n = 2π n / N`` for shift index ``n`` (an integer or an array of them)."""
        if np.ndim(n) == 0:
            return 2.0 * math.pi * int(n) / self.shifts
        return 2.0 * np.pi * np.asarray(n, np.float64) / self.shifts

    @property
    def shifts_rad(self) -> np.ndarray:
        """Every step, ``δ_n`` for n = 0 … N-1."""
        return 2.0 * np.pi * np.arange(self.shifts) / self.shifts

    def frame(self, direction: str, period_index: int, shift_index: int) -> FringeFrame:
        """Frame ``(d, k, n)`` of the coding (``n`` may be any step; ``k`` one of the
        periods)."""
        return FringeFrame(
            direction,
            period_index,
            shift_index,
            self.periods_mm[period_index],
            float(self.shift_rad(shift_index)),
            self.offset,
            self.amplitude,
        )

    def frames(self) -> tuple[FringeFrame, ...]:
        """Every frame of the coding, in the order a station shows them: direction by
        direction (``directions``), period by period (finest first), shift by shift; frame
        ``(d, k, n)`` is number ``(d K + k) N + n``."""
        return tuple(
            self.frame(direction, k, n)
            for direction in self.directions
            for k in range(len(self.periods_mm))
            for n in range(self.shifts)
        )

    def white(self) -> FringeFrame:
        """The screen's uniform white (commanded 1, displayed 1 above the black level):
        the frame whose image is each pixel's response to the screen's full scale."""
        return FringeFrame(self.directions[0], -1, -1, self.periods_mm[-1], 0.0, 1.0, 0.0)

    # ------------------------------------------------------------ the screen
    def screen(self) -> ScreenResponse:
        """How the screen turns commanded values into radiance (its levels, response,
        black level and ambient light)."""
        curve = (
            read_response(self.screen_response_file)
            if self.screen_response_file is not None
            else None
        )
        return ScreenResponse(
            self.levels, self.gamma, curve, self.screen_black_level, self.screen_ambient
        )

    @property
    def level_step(self) -> float:
        """One grey level of the commanded value, ``1 / (levels - 1)`` (0: continuous)."""
        return 1.0 / (self.levels - 1) if self.levels else 0.0

    @property
    def peak_commanded(self) -> float:
        """The brightest value the sequence commands: ``offset + amplitude``, at most 1."""
        return min(1.0, self.offset + self.amplitude)

    def displayed(self, commanded: np.ndarray) -> np.ndarray:
        """What the screen shows for commanded values (float64; NaN kept)."""
        return self.screen().displayed(commanded)

    def brightest(self) -> float:
        """The brightest radiance the sequence displays: :attr:`peak_commanded`,
        quantised, through the response, above the black level."""
        return float(self.displayed(np.array([self.peak_commanded]))[0])

    def largest_step(self) -> float:
        """The largest difference between neighbouring displayed levels (0: continuous)."""
        if not self.levels:
            return 0.0
        return float(np.diff(self.displayed(np.linspace(0.0, 1.0, self.levels))).max())

    # ------------------------------------------------------------ the formula
    def frame_radiance(self, frame: FringeFrame, s_mm: np.ndarray) -> np.ndarray:
        """``frame`` as this screen displays it at ``s_mm`` (mm from the screen's edge
        along the frame's direction): :func:`displayed_fringe`."""
        return displayed_fringe(
            self.screen(), s_mm, frame.period_mm, frame.shift_rad, frame.offset, frame.amplitude
        )

    def radiance(self, s_mm: np.ndarray, period_index: int, shift_index: int) -> np.ndarray:
        """What coded frame ``(k, n)`` displays at ``s_mm`` (mm from the screen's edge)."""
        return displayed_fringe(
            self.screen(),
            s_mm,
            self.periods_mm[period_index],
            self.shift_rad(shift_index),
            self.offset,
            self.amplitude,
        )

    def sequence(self, s_mm: np.ndarray) -> np.ndarray:
        """Every coded frame of one direction at ``s_mm``: shape ``(K, N) + s_mm.shape``
        (the synthetic sequence a station would record off a perfect mirror)."""
        return np.stack(
            [
                np.stack([self.radiance(s_mm, k, n) for n in range(self.shifts)])
                for k in range(len(self.periods_mm))
            ]
        )


def _check_periods(codec: FringeCodec) -> None:
    """The periods increasing from the finest (above :data:`MIN_PERIOD_MM`), the coarsest
    at most :data:`MAX_PERIOD_SCREENS` times the screen's larger extent and at least its
    extent along each coded direction."""
    periods, half = codec.periods_mm, codec.screen_half_size_mm
    if (
        any(b <= a for a, b in zip(periods, periods[1:], strict=False))
        or periods[0] <= MIN_PERIOD_MM
    ):
        raise SceneError(
            "emitter.periods",
            f"periods above {MIN_PERIOD_MM:g} mm increasing from the finest",
            list(periods),
        )
    extent = 2.0 * max(half)
    limit = MAX_PERIOD_SCREENS * extent
    if periods[-1] > limit:
        raise SceneError(
            "emitter.periods",
            f"periods in ({MIN_PERIOD_MM:g}, {limit:g}] mm (the coarsest at most "
            f"{MAX_PERIOD_SCREENS:g} times the screen's extent 2 half_size = {extent:g} mm)",
            periods[-1],
        )
    for direction in codec.directions:
        along = 2.0 * half[axis_of(direction)]
        if periods[-1] < along:
            raise SceneError(
                "emitter.periods",
                f"a coarsest period of at least the screen's extent along {direction!r}, "
                f"2 half_size = {along:g} mm (else the phase is ambiguous)",
                periods[-1],
            )
