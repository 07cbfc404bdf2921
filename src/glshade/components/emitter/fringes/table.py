"""The fringe emitter's table: sinusoidal fringes of several periods, each shown at ``N``
phase shifts along ``v`` and ``u``, and which one frame of that sequence the scene shows.

Frame ``(d, k, n)`` commands ``L = offset + amplitude cos(2π s / periods[k] - 2π n / N)``
with ``s`` the distance from the screen's edge along ``d`` (``v + half_size[1]`` or
``u + half_size[0]``), quantised to ``levels`` grey levels and displayed as
``commanded ** gamma`` (:func:`displayed`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any, cast

import numpy as np

from glshade.components.emitter.fringes.screen import ScreenResponse, read_response
from glshade.components.emitter.stripes.table import Emitter as StripesTable
from glshade.components.emitter.table import MIN_PERIOD_MM
from glshade.errors import SceneError
from glshade.params import PARAM_KEY, Control, Table, param

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


def _shared(name: str) -> Any:
    """The stripes' declaration of the screen's geometry (``distance``, ``half_size``):
    the same parameter, shared by every emitter on that plane."""
    item = next(f for f in fields(StripesTable) if f.name == name)
    return field(default=item.default, metadata={PARAM_KEY: item.metadata[PARAM_KEY]})


@dataclass(frozen=True)
class FringeFrame:
    """One frame a fringe screen shows: ``offset + amplitude cos(2π s / period_mm -
    shift_rad)`` along ``direction`` (``"v"`` or ``"u"``), quantised and displayed as every
    frame is. ``period_index`` and ``shift_index`` place it in its sequence (``-1``: a
    frame outside the coding, the uniform white screen of :meth:`FringesTable.white`)."""

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
        return DIRECTIONS.index(self.direction) ^ 1

    @property
    def coded(self) -> bool:
        """A frame of the coding (not the white screen)."""
        return self.period_index >= 0


def displayed(commanded: np.ndarray, levels: int, gamma: float) -> np.ndarray:
    """What a screen of ``levels`` grey levels and response ``commanded ** gamma`` shows
    (float64), no black level, no ambient light: clamped to ``[0, 1]``, rounded to the
    nearest of ``levels`` grey levels ``j / (levels - 1)`` (halves up: ``floor(c (levels -
    1) + 0.5)``; ``levels = 0``: not rounded), then ``** gamma``
    (:meth:`~glshade.components.emitter.fringes.screen.ScreenResponse.displayed`)."""
    return ScreenResponse(levels, gamma).displayed(commanded)


def _check(values: dict[str, Any]) -> None:
    """The sequence and the screen together, where the fringes are the scene's emitter
    (a scene of another emitter keeps these values unchecked together, as it keeps them)."""
    if values.get("kind") != "fringes":
        return
    periods, half = values["periods"], values["half_size"]
    if (
        any(b <= a for a, b in zip(periods, periods[1:], strict=False))
        or periods[0] <= MIN_PERIOD_MM
    ):
        raise SceneError(
            "emitter.periods",
            f"periods above {MIN_PERIOD_MM:g} mm increasing from the finest",
            list(periods),
        )
    _check_coarsest(periods, half)
    if values["levels"] == 1:
        raise SceneError("emitter.levels", "0 (continuous) or at least 2 grey levels", 1)
    _check_screen(values)
    if values["offset"] + values["amplitude"] > 1.0:
        raise SceneError(
            "emitter.offset",
            f"offset + amplitude <= 1 (the screen's full scale; amplitude is "
            f"{values['amplitude']:g})",
            values["offset"],
        )
    for direction in values["directions"]:
        extent = 2.0 * half[DIRECTIONS.index(direction) ^ 1]
        if periods[-1] < extent:
            raise SceneError(
                "emitter.periods",
                f"a coarsest period of at least the screen's extent along {direction!r}, "
                f"2 half_size = {extent:g} mm (else the phase is ambiguous)",
                periods[-1],
            )
    if values["frame_period_index"] >= len(periods):
        raise SceneError(
            "emitter.frame_period_index",
            f"an index into emitter.periods, 0 to {len(periods) - 1}",
            values["frame_period_index"],
        )
    if values["frame_shift_index"] >= values["shifts"]:
        raise SceneError(
            "emitter.frame_shift_index",
            f"a phase step 0 to shifts - 1 = {values['shifts'] - 1}",
            values["frame_shift_index"],
        )


def _check_coarsest(periods: tuple[float, ...], half: tuple[float, float]) -> None:
    """The coarsest period at most :data:`MAX_PERIOD_SCREENS` times the screen's larger
    extent (the periods are finite and increasing: checked before)."""
    extent = 2.0 * max(half)
    limit = MAX_PERIOD_SCREENS * extent
    if periods[-1] > limit:
        raise SceneError(
            "emitter.periods",
            f"periods in ({MIN_PERIOD_MM:g}, {limit:g}] mm (the coarsest at most "
            f"{MAX_PERIOD_SCREENS:g} times the screen's extent 2 half_size = {extent:g} mm)",
            periods[-1],
        )


def _check_screen(values: dict[str, Any]) -> None:
    """The real screen's parts together: one response (a gamma or a measured curve), a
    pixel no larger than the screen."""
    if values["response_file"] is not None:
        if values["gamma"] != 1.0:
            raise SceneError(
                "emitter.gamma",
                "1 where emitter.response_file gives the screen's measured response (one "
                "response: a gamma or a curve)",
                values["gamma"],
            )
        read_response(values["response_file"])
    pitch, half = values["pixel_pitch"], values["half_size"]
    if pitch > 2.0 * min(half):
        raise SceneError(
            "emitter.pixel_pitch",
            f"0 (a continuous screen) or a pitch within the screen's {2.0 * min(half):g} mm",
            pitch,
        )


@dataclass(frozen=True)
class FringesTable(Table):
    """The fringe sequence (``periods`` in mm, finest first; ``shifts`` phase steps;
    ``directions``), the screen (``offset``, ``amplitude``, ``gamma``, ``levels``) and the
    frame the scene shows (``frame_direction``, ``frame_period_index``,
    ``frame_shift_index``)."""

    table = "emitter"
    table_checks = (_check,)

    distance: float = _shared("distance")
    half_size: tuple[float, float] = _shared("half_size")
    periods: tuple[float, ...] = param(
        "emitter.periods", "mm", (2.0, 16.0, 128.0, 1024.0),
        "fringe periods, finest first; the coarsest at least the screen's extent "
        "2 half_size along each direction, and at most 1e6 times its larger extent",
        value_type="vector",
    )  # fmt: skip
    shifts: int = param(
        "emitter.shifts", "", 4, "phase steps per period, N >= 3 (step 2π n / N)",
        value_type="integer", lo=3, hi=MAX_SHIFTS, control=Control("shifts", 3, 16, fmt="%d"),
    )  # fmt: skip
    directions: tuple[str, ...] = param(
        "emitter.directions", "", DIRECTIONS,
        'the sequence\'s directions: "v" (fringes of constant v, like the stripes), '
        '"u" (crossed)', value_type="names", choices=DIRECTIONS,
    )  # fmt: skip
    offset: float = param(
        "emitter.offset", "", 0.5, "mean commanded value (offset + amplitude <= 1)",
        lo=0.0, closed=True, control=Control("offset", 0.0, 1.0, fmt="%.3f"),
    )  # fmt: skip
    amplitude: float = param(
        "emitter.amplitude", "", 0.5, "commanded modulation (offset + amplitude <= 1)",
        lo=0.0, closed=True, control=Control("amplitude", 0.0, 1.0, fmt="%.3f"),
    )  # fmt: skip
    gamma: float = param(
        "emitter.gamma", "", 1.0, "the screen's response: displayed = commanded ** gamma",
        lo=0.0, control=Control("gamma", 0.2, 5.0, log=True, fmt="%.2f"),
    )  # fmt: skip
    levels: int = param(
        "emitter.levels", "", 256, "commanded grey levels of the screen (0: continuous; never 1)",
        value_type="integer", lo=0, hi=MAX_LEVELS,
        control=Control("levels", 0, 4096, log=True, fmt="%d"),
    )  # fmt: skip
    black_level: float = param(
        "emitter.black_level", "", 0.0,
        "the screen's radiance at commanded black over its white (1 / its contrast ratio): "
        "an offset in every frame",
        lo=0.0, hi=0.5, closed=True, control=Control("black level", 0.0, 0.1, fmt="%.4f"),
    )  # fmt: skip
    ambient: float = param(
        "emitter.ambient", "", 0.0,
        "the room light the screen's face reflects, in units of its white: an offset in "
        "every frame, the black matrix included",
        lo=0.0, closed=True, plausible_max=1.0,
        plausible_why="more room light than the screen's own white",
        control=Control("ambient", 0.0, 0.2, fmt="%.4f"),
    )  # fmt: skip
    response_file: str | None = param(
        "emitter.response_file", "", None,
        "the screen's measured response instead of a gamma: a text file of commanded, "
        "displayed pairs (commanded from 0 to its full scale; displayed in any unit, taken "
        "as (L - L(0)) / (L(full) - L(0)))",
        value_type="path", role="feature",
    )  # fmt: skip
    pixel_pitch: float = param(
        "emitter.pixel_pitch", "mm", 0.0,
        "the screen's pixel pitch: a fringe is shown on pixels, each ray seeing the value at "
        "the centre of the pixel it lands in; 0: a continuous screen",
        lo=0.0, closed=True, role="feature",
    )  # fmt: skip
    fill_factor: float = param(
        "emitter.fill_factor", "", 1.0,
        "the share of each screen pixel's area that emits, a centred square; the black "
        "matrix between shows only the ambient light (with emitter.pixel_pitch)",
        lo=0.01, hi=1.0, closed=True,
    )  # fmt: skip
    glass_thickness: float = param(
        "emitter.glass_thickness", "mm", 0.0,
        "the screen's cover glass in front of its emitting layer: rays refract through it "
        "(0: none)",
        lo=0.0, closed=True, hi=100.0, role="feature",
    )  # fmt: skip
    glass_index: float = param(
        "emitter.glass_index", "", 1.52, "the cover glass's refractive index",
        lo=1.0, hi=4.0, closed=True,
    )  # fmt: skip
    footprint_samples: int = param(
        "emitter.footprint_samples", "", 64,
        "points of a reflection lobe's kernel per value over a pixelated screen (no closed "
        "form there)",
        value_type="integer", lo=1, hi=4096,
    )  # fmt: skip
    frame_direction: str = param(
        "emitter.frame_direction", "", "v",
        "the frame shown: its direction (v or u; it need not be one the sequence codes)",
        value_type="choice", choices=DIRECTIONS,
    )  # fmt: skip
    frame_period_index: int = param(
        "emitter.frame_period_index", "", 0, "the frame shown: its period, an index into periods",
        value_type="integer", lo=0, hi=1023, control=Control("frame_period", 0, 7, fmt="%d"),
    )  # fmt: skip
    frame_shift_index: int = param(
        "emitter.frame_shift_index", "", 0,
        "the frame shown: its phase step n, 0 to shifts - 1", value_type="integer", lo=0,
        hi=MAX_SHIFTS - 1, control=Control("frame_shift", 0, 15, fmt="%d"),
    )  # fmt: skip

    def clamp(self, name: str, value: Any) -> Any:
        """Offset and amplitude within the screen's full scale together; the frame shown
        one of the sequence's (its shift below ``shifts``, its period one of
        ``periods``); never 1 grey level."""
        limits = {
            "offset": lambda v: min(v, 1.0 - self.amplitude),
            "amplitude": lambda v: min(v, 1.0 - self.offset),
            "shifts": lambda v: max(v, self.frame_shift_index + 1),
            "frame_shift_index": lambda v: min(v, self.shifts - 1),
            "frame_period_index": lambda v: min(v, len(self.periods) - 1),
            "levels": lambda v: 2 if v == 1 else v,
        }
        return limits[name](value) if name in limits else super().clamp(name, value)

    # ---------------------------------------------------------------- the frame
    @property
    def axis(self) -> int:
        """The screen coordinate the frame's fringes vary along: 0 for ``u``, 1 for ``v``."""
        return DIRECTIONS.index(self.frame_direction) ^ 1

    @property
    def frame_period(self) -> float:
        return self.periods[self.frame_period_index]

    @property
    def frame_step(self) -> float:
        """The frame's phase step ``2π n / N`` (rad)."""
        return 2.0 * math.pi * self.frame_shift_index / self.shifts

    def screen(self) -> ScreenResponse:
        """How the screen turns commanded values into radiance (its levels, response,
        black level and ambient light)."""
        curve = read_response(self.response_file) if self.response_file is not None else None
        return ScreenResponse(self.levels, self.gamma, curve, self.black_level, self.ambient)

    def shown(self) -> FringeFrame:
        """The frame the scene shows alone (its ``frame_*`` values)."""
        return FringeFrame(
            self.frame_direction,
            self.frame_period_index,
            self.frame_shift_index,
            self.frame_period,
            self.frame_step,
            self.offset,
            self.amplitude,
        )

    def fringe_radiance(self, along: np.ndarray) -> np.ndarray:
        """The displayed radiance (float64) at screen coordinate ``along`` (mm: ``v`` for a
        ``"v"`` frame, ``u`` for a ``"u"`` frame) of a continuous screen; NaN propagates."""
        return frame_radiance(
            self.shown(), self.screen(), np.asarray(along, np.float64) + self.half_size[self.axis]
        )

    def radiance_uv(self, u: np.ndarray, v: np.ndarray, frame: FringeFrame | None = None):
        """What the screen shows at screen points ``(u, v)`` (mm; float64, NaN propagates):
        ``frame`` (default: the scene's own), on the screen's pixels where it has a pitch
        (the value at the centre of the pixel a point lies in; the black matrix shows the
        ambient light)."""
        frame = frame or self.shown()
        s = [np.asarray(c, np.float64) + h for c, h in zip((u, v), self.half_size, strict=True)]
        if not self.pixel_pitch:
            return frame_radiance(frame, self.screen(), s[frame.axis])
        pitch = self.pixel_pitch
        centres = [(np.floor(c / pitch) + 0.5) * pitch for c in s]
        lit = 0.5 * math.sqrt(self.fill_factor) * pitch
        with np.errstate(invalid="ignore"):
            dark = np.maximum(np.abs(s[0] - centres[0]), np.abs(s[1] - centres[1])) > lit
        values = frame_radiance(frame, self.screen(), centres[frame.axis])
        return np.where(dark, self.ambient, values)

    def harmonics(self, frame: FringeFrame) -> np.ndarray:
        """The cosine series ``b_0 … b_7`` of ``frame``'s displayed radiance against its
        phase, as it averages over the screen's pixels (the fill factor's share of it, the
        ambient light between)."""
        series = self.screen().harmonics(frame.offset, frame.amplitude)
        if self.pixel_pitch:
            series = self.fill_factor * series
            series[0] += (1.0 - self.fill_factor) * self.ambient
        return series

    # ------------------------------------------------------------- the sequence
    def sequence(self) -> tuple[FringeFrame, ...]:
        """Every frame of the coding, in the order a station shows them: direction by
        direction (``directions``), period by period (finest first), shift by shift; frame
        ``(d, k, n)`` is number ``(d K + k) N + n``."""
        return tuple(
            FringeFrame(
                direction,
                k,
                n,
                period,
                2.0 * math.pi * n / self.shifts,
                self.offset,
                self.amplitude,
            )
            for direction in self.directions
            for k, period in enumerate(self.periods)
            for n in range(self.shifts)
        )

    def white(self) -> FringeFrame:
        """The screen's uniform white (commanded 1, displayed 1): the frame whose image is
        each pixel's response to the screen's full scale."""
        return FringeFrame(self.directions[0], -1, -1, self.periods[-1], 0.0, 1.0, 0.0)

    def showing(self, frame: FringeFrame) -> dict[str, Any]:
        """The table's values that make the scene show ``frame`` (a coded frame: its
        ``frame_*`` indices; the white screen: offset 1 and amplitude 0)."""
        if frame.coded:
            return {
                "frame_direction": frame.direction,
                "frame_period_index": frame.period_index,
                "frame_shift_index": frame.shift_index,
            }
        return {"offset": frame.offset, "amplitude": frame.amplitude}

    def brightest(self) -> float:
        """The brightest radiance the sequence displays: ``offset + amplitude`` (at most
        the screen's white), quantised, through the response, above the black level."""
        top = np.array([min(1.0, self.offset + self.amplitude)])
        return float(self.screen().displayed(top)[0])

    def largest_step(self) -> float:
        """The largest difference between neighbouring displayed levels (0: continuous)."""
        if not self.levels:
            return 0.0
        return float(np.diff(self.screen().displayed(np.linspace(0.0, 1.0, self.levels))).max())


def frame_radiance(frame: FringeFrame, screen: ScreenResponse, s_mm: np.ndarray) -> np.ndarray:
    """``frame`` displayed at ``s_mm`` (mm from the screen's edge along its direction):
    ``screen.displayed(offset + amplitude cos(2π x - shift))``, ``x`` the fraction of the
    period at ``s`` (float64, as the shader reduces it)."""
    x = np.asarray(s_mm, np.float64) / frame.period_mm
    x = x - np.floor(x)
    commanded = frame.offset + frame.amplitude * np.cos(2.0 * math.pi * x - frame.shift_rad)
    return screen.displayed(commanded)


def fringes_of(scene: Any) -> FringesTable:
    """A scene's emitter table as the fringes' (typed: the scene declares the stripes'
    table, the fringes' fields join it at run time)."""
    return cast(FringesTable, scene.emitter)
