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
    """What the screen shows for commanded values (float64): clamped to ``[0, 1]``,
    rounded to the nearest of ``levels`` grey levels ``j / (levels - 1)`` (halves up:
    ``floor(c (levels - 1) + 0.5)``; ``levels = 0``: not rounded), then ``** gamma``."""
    c = np.clip(np.asarray(commanded, np.float64), 0.0, 1.0)
    if levels:
        c = np.floor(c * (levels - 1) + 0.5) / (levels - 1)
    return c**gamma


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
    if values["levels"] == 1:
        raise SceneError("emitter.levels", "0 (continuous) or at least 2 grey levels", 1)
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
        "2 half_size along each direction", value_type="vector",
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

    def fringe_radiance(self, along: np.ndarray) -> np.ndarray:
        """The displayed radiance (float64) at screen coordinate ``along`` (mm: ``v`` for a
        ``"v"`` frame, ``u`` for a ``"u"`` frame); NaN propagates."""
        s = np.asarray(along, np.float64) + self.half_size[self.axis]
        x = s / self.frame_period
        x = x - np.floor(x)
        commanded = self.offset + self.amplitude * np.cos(2.0 * math.pi * x - self.frame_step)
        return displayed(commanded, self.levels, self.gamma)

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
        the screen's white), quantised and through the gamma."""
        top = np.array([min(1.0, self.offset + self.amplitude)])
        return float(displayed(top, self.levels, self.gamma)[0])

    def largest_step(self) -> float:
        """The largest difference between neighbouring displayed levels (0: continuous)."""
        if not self.levels:
            return 0.0
        return float(np.diff(np.linspace(0.0, 1.0, self.levels) ** self.gamma).max())


def fringes_of(scene: Any) -> FringesTable:
    """A scene's emitter table as the fringes' (typed: the scene declares the stripes'
    table, the fringes' fields join it at run time)."""
    return cast(FringesTable, scene.emitter)
