"""The fringe emitter's table: sinusoidal fringes of several periods, each shown at ``N``
phase shifts along ``v`` and ``u``, and which one frame of that sequence the scene shows.

The coding itself (the sequence, the commanded fringe, the screen that displays it, their
rules and the formula of a frame's radiance) is the table's
:class:`~glshade.components.emitter.fringes.codec.FringeCodec`, made and validated once
with the table (:attr:`FringesTable.codec`); the table adds the frame shown, the screen's
pixels and its cover glass.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from glshade.components.emitter.fringes.codec import (
    AMBIENT,
    AMPLITUDE,
    BLACK_LEVEL,
    DIRECTIONS,
    DIRECTIONS_PARAM,
    GAMMA,
    LEVELS,
    MAX_LEVELS,
    MAX_PERIOD_SCREENS,
    MAX_SHIFTS,
    OFFSET,
    PERIODS,
    RESPONSE_FILE,
    SHIFTS,
    FringeCodec,
    FringeFrame,
    axis_of,
)
from glshade.components.emitter.fringes.screen import ScreenResponse
from glshade.components.emitter.stripes.table import Emitter as StripesTable
from glshade.components.emitter.stripes.table import check_sag
from glshade.errors import SceneError
from glshade.params import PARAM_KEY, Control, Param, Table, param

__all__ = [
    "DIRECTIONS",
    "MAX_LEVELS",
    "MAX_PERIOD_SCREENS",
    "MAX_SHIFTS",
    "FringeCodec",
    "FringeFrame",
    "FringesTable",
    "fringes_of",
]


def _shared(name: str) -> Any:
    """The stripes' declaration of the screen's geometry (``distance``, ``half_size``, its
    pose and its ``sag``): the same parameter, shared by every emitter on that plane."""
    item = next(f for f in fields(StripesTable) if f.name == name)
    return field(default=item.default, metadata={PARAM_KEY: item.metadata[PARAM_KEY]})


def _declared(declared: Param) -> Any:
    """A field of the coding's parameter ``declared`` (declared once, beside the codec
    that checks a value given to it directly against the same declaration)."""
    return field(default=declared.default, metadata={PARAM_KEY: declared})


def _check(values: dict[str, Any]) -> None:
    """The frame shown and the screen's pixels, where the fringes are the scene's emitter
    (a scene of another emitter keeps these values unchecked together, as it keeps them;
    the coding's own rules are the codec's: :meth:`FringesTable.__post_init__`)."""
    if values.get("kind") != "fringes":
        return
    pitch, half = values["pixel_pitch"], values["half_size"]
    if pitch > 2.0 * min(half):
        raise SceneError(
            "emitter.pixel_pitch",
            f"0 (a continuous screen) or a pitch within the screen's {2.0 * min(half):g} mm",
            pitch,
        )
    if values["frame_period_index"] >= len(values["periods"]):
        raise SceneError(
            "emitter.frame_period_index",
            f"an index into emitter.periods, 0 to {len(values['periods']) - 1}",
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
    ``directions``), the screen (``offset``, ``amplitude``, ``gamma``, ``levels``, its
    black level, room light, response, pixels and cover glass) and the frame the scene
    shows (``frame_direction``, ``frame_period_index``, ``frame_shift_index``). Where the
    fringes are the scene's emitter, the table's :attr:`codec` is made (and so the coding
    validated) with it."""

    table = "emitter"
    table_checks = (_check, check_sag)

    distance: float = _shared("distance")
    half_size: tuple[float, float] = _shared("half_size")
    pose: str = _shared("pose")
    centre: tuple[float, float, float] | None = _shared("centre")
    look_at: tuple[float, float, float] = _shared("look_at")
    up: tuple[float, float, float] = _shared("up")
    yaw_deg: float = _shared("yaw_deg")
    pitch_deg: float = _shared("pitch_deg")
    roll_deg: float = _shared("roll_deg")
    sag: tuple[float, float, float] = _shared("sag")
    # the coding's parameters, declared by the codec (glshade.components.emitter.fringes.codec)
    periods: tuple[float, ...] = _declared(PERIODS)
    shifts: int = _declared(SHIFTS)
    directions: tuple[str, ...] = _declared(DIRECTIONS_PARAM)
    offset: float = _declared(OFFSET)
    amplitude: float = _declared(AMPLITUDE)
    gamma: float = _declared(GAMMA)
    levels: int = _declared(LEVELS)
    black_level: float = _declared(BLACK_LEVEL)
    ambient: float = _declared(AMBIENT)
    response_file: str | None = _declared(RESPONSE_FILE)
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

    def __post_init__(self) -> None:
        super().__post_init__()
        if getattr(self, "kind", None) == "fringes":
            object.__setattr__(self, "_codec", FringeCodec.of(self))

    @property
    def codec(self) -> FringeCodec:
        """The table's fringe coding: made, and so validated, once (with the table where
        the fringes are the scene's emitter, else here, at the first use)."""
        codec = self.__dict__.get("_codec")
        if codec is None:
            codec = FringeCodec.of(self)
            object.__setattr__(self, "_codec", codec)
        return cast(FringeCodec, codec)

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
        return axis_of(self.frame_direction)

    @property
    def frame_period(self) -> float:
        return self.periods[self.frame_period_index]

    def screen(self) -> ScreenResponse:
        """How the screen turns commanded values into radiance (the codec's)."""
        return self.codec.screen()

    def shown(self) -> FringeFrame:
        """The frame the scene shows alone (its ``frame_*`` values)."""
        return self.codec.frame(
            self.frame_direction, self.frame_period_index, self.frame_shift_index
        )

    def fringe_radiance(self, along: np.ndarray) -> np.ndarray:
        """The displayed radiance (float64) at screen coordinate ``along`` (mm: ``v`` for a
        ``"v"`` frame, ``u`` for a ``"u"`` frame) of a continuous screen; NaN propagates."""
        s = np.asarray(along, np.float64) + self.half_size[self.axis]
        return self.codec.frame_radiance(self.shown(), s)

    def radiance_uv(
        self, u: np.ndarray, v: np.ndarray, frame: FringeFrame | None = None
    ) -> NDArray[np.float64]:
        """What the screen shows at screen points ``(u, v)`` (mm; float64, NaN propagates):
        ``frame`` (default: the scene's own), on the screen's pixels where it has a pitch
        (the value at the centre of the pixel a point lies in; the black matrix shows the
        ambient light)."""
        frame = frame or self.shown()
        s = [np.asarray(c, np.float64) + h for c, h in zip((u, v), self.half_size, strict=True)]
        if not self.pixel_pitch:
            return self.codec.frame_radiance(frame, s[frame.axis])
        pitch = self.pixel_pitch
        centres = [(np.floor(c / pitch) + 0.5) * pitch for c in s]
        lit = 0.5 * math.sqrt(self.fill_factor) * pitch
        with np.errstate(invalid="ignore"):
            dark = np.maximum(np.abs(s[0] - centres[0]), np.abs(s[1] - centres[1])) > lit
        values = self.codec.frame_radiance(frame, centres[frame.axis])
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
        """Every frame of the coding, in the order a station shows them
        (:meth:`FringeCodec.frames`)."""
        return self.codec.frames()

    def white(self) -> FringeFrame:
        """The screen's uniform white (:meth:`FringeCodec.white`)."""
        return self.codec.white()

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
        """The brightest radiance the sequence displays (:meth:`FringeCodec.brightest`)."""
        return self.codec.brightest()

    def largest_step(self) -> float:
        """The largest difference between neighbouring displayed levels (0: continuous)."""
        return self.codec.largest_step()


def fringes_of(scene: Any) -> FringesTable:
    """A scene's emitter table as the fringes' (typed: the scene declares the stripes'
    table, the fringes' fields join it at run time)."""
    return cast(FringesTable, scene.emitter)
