"""A recorded fringe capture: the frames as a camera recorded them and the coding that
says what each frame shows (docs/captures.md).

:class:`CaptureCoding` describes a coding in the terms a station's own software uses
(its frame order, its period unit, its shift sign, where its screen coordinate starts)
and translates it into glshade's (:meth:`CaptureCoding.codec`,
:meth:`CaptureCoding.glshade_order`): glshade's decoder reads it unchanged."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from glshade.capture.response import Response
from glshade.components.emitter.fringes.codec import DIRECTIONS, FringeCodec, axis_of
from glshade.errors import GlshadeError

#: The nesting levels of a frame sequence.
LEVELS = ("direction", "period", "shift")
#: Where a screen coordinate's 0 lies: at ``-half_size`` growing with the axis, or at
#: ``+half_size`` growing against it.
ORIGINS = ("low", "high")
PERIOD_UNITS = ("mm", "screen")


@dataclass(frozen=True)
class CaptureCoding:
    """What a recorded sequence codes, in its own conventions.

    ``directions``: in frame order, ``"v"`` (fringes vary along v) or ``"u"``;
    ``periods``: in frame order, in ``period_unit`` (``"mm"``, or ``"screen"``: fringes
    per screen, period = the screen's extent along the direction / value); ``order``: the
    nesting of the frames, outermost first (a permutation of :data:`LEVELS`); ``shifts``:
    N phase steps; ``shift_sign``: +1 for frames ``A + B cos(2π s / p - 2π n / N)``, -1
    for ``A + B cos(2π s / p + 2π n / N)``; ``origin``: per screen axis (u, v), where
    ``s`` is 0 (:data:`ORIGINS`); ``screen_size_mm``: the screen's (u, v) extent;
    ``offset``, ``amplitude``: the commanded fringe where known (defaults 0.5, 0.5)."""

    directions: tuple[str, ...]
    periods: tuple[float, ...]
    shifts: int
    screen_size_mm: tuple[float, float]
    period_unit: str = "mm"
    order: tuple[str, ...] = LEVELS
    shift_sign: int = 1
    origin: tuple[str, str] = ("low", "low")
    offset: float | None = None
    amplitude: float | None = None

    def __post_init__(self) -> None:
        set_ = object.__setattr__
        set_(self, "directions", tuple(str(d) for d in self.directions))
        set_(self, "periods", tuple(float(p) for p in self.periods))
        set_(self, "order", tuple(str(o) for o in self.order))
        set_(self, "origin", tuple(str(o) for o in self.origin))
        set_(self, "screen_size_mm", tuple(float(s) for s in self.screen_size_mm))
        if not self.directions or any(d not in DIRECTIONS for d in self.directions):
            raise GlshadeError(f"coding.directions: each v or u, got {list(self.directions)}")
        if len(set(self.directions)) != len(self.directions):
            raise GlshadeError(f"coding.directions: each at most once, got {list(self.directions)}")
        if not self.periods or any(not np.isfinite(p) or p <= 0 for p in self.periods):
            raise GlshadeError(f"coding.periods: positive numbers, got {list(self.periods)}")
        if self.period_unit not in PERIOD_UNITS:
            raise GlshadeError(f"coding.period_unit: mm or screen, got {self.period_unit!r}")
        if sorted(self.order) != sorted(LEVELS):
            raise GlshadeError(
                f"coding.order: a permutation of {', '.join(LEVELS)}, got {list(self.order)}"
            )
        if int(self.shifts) != self.shifts or self.shifts < 3:
            raise GlshadeError(f"coding.shifts: an integer of at least 3, got {self.shifts}")
        set_(self, "shifts", int(self.shifts))
        if self.shift_sign not in (1, -1):
            raise GlshadeError(f"coding.shift_sign: +1 or -1, got {self.shift_sign}")
        if len(self.origin) != 2 or any(o not in ORIGINS for o in self.origin):
            raise GlshadeError(f"coding.origin: two of low, high (u, v), got {list(self.origin)}")
        size = self.screen_size_mm
        if len(size) != 2 or any(not np.isfinite(s) or s <= 0 for s in size):
            raise GlshadeError(f"coding.screen_size_mm: two positive numbers, got {list(size)}")
        for direction in self.directions:  # glshade's rules (the coarsest period spans the screen)
            try:
                self.codec(direction)
            except GlshadeError as error:
                text = str(error).replace("emitter.", "coding.")
                raise GlshadeError(f"{text} (in mm along {direction})") from None

    # ------------------------------------------------------------ counts
    @property
    def frame_count(self) -> int:
        """The frames the sequence holds."""
        return len(self.directions) * len(self.periods) * self.shifts

    def period_mm(self, direction: str, index: int) -> float:
        """Period ``index`` (frame order) along ``direction`` in mm."""
        value = self.periods[index]
        if self.period_unit == "mm":
            return value
        return self.screen_size_mm[axis_of(direction)] / value

    def finest_first(self, direction: str) -> list[int]:
        """The period indices (frame order) from the finest to the coarsest."""
        return sorted(range(len(self.periods)), key=lambda k: self.period_mm(direction, k))

    def frame_index(self, d: int, k: int, n: int) -> int:
        """The recorded frame of direction ``d``, period ``k``, shift ``n`` (frame order)."""
        sizes = {"direction": len(self.directions), "period": len(self.periods)}
        sizes["shift"] = self.shifts
        where = {"direction": d, "period": k, "shift": n}
        index = 0
        for level in self.order:
            index = index * sizes[level] + where[level]
        return index

    # ------------------------------------------------------------ glshade's terms
    def codec(self, direction: str | None = None) -> FringeCodec:
        """The equivalent :class:`FringeCodec` (mm, finest first): of ``direction`` alone,
        or of every direction where their periods in mm agree (None)."""
        chosen = self.directions if direction is None else (direction,)
        periods = {tuple(self.period_mm(d, k) for k in self.finest_first(d)) for d in chosen}
        if len(periods) != 1:
            raise GlshadeError(
                "coding: the directions' periods differ in mm (screen units on a screen that "
                "is not square): ask for one direction's codec"
            )
        half = (0.5 * self.screen_size_mm[0], 0.5 * self.screen_size_mm[1])
        offset = 0.5 if self.offset is None else self.offset
        amplitude = 0.5 if self.amplitude is None else self.amplitude
        return FringeCodec(
            periods_mm=periods.pop(),
            shifts=self.shifts,
            directions=tuple(chosen),
            offset=offset,
            amplitude=amplitude,
            levels=0,
            screen_half_size_mm=half,
        )

    def glshade_order(self, frames: np.ndarray) -> dict[str, np.ndarray]:
        """Per direction, the ``(K finest first, N, H, W)`` block glshade's decoder takes:
        glshade's shift ``m`` is the recorded shift ``n = m`` (sign +1) or ``n = -m mod N``
        (sign -1: ``cos(φ + 2π n / N) = cos(φ - 2π m / N)``)."""
        frames = np.asarray(frames)
        if frames.ndim != 3 or frames.shape[0] != self.frame_count:
            raise GlshadeError(
                f"capture: {self.frame_count} frames for this coding, got "
                f"{frames.shape[0] if frames.ndim == 3 else frames.shape}"
            )
        out = {}
        for d, direction in enumerate(self.directions):
            index = [
                [
                    self.frame_index(d, k, (self.shift_sign * m) % self.shifts)
                    for m in range(self.shifts)
                ]
                for k in self.finest_first(direction)
            ]
            out[direction] = frames[np.asarray(index)]
        return out

    # ------------------------------------------------------------ files
    def to_dict(self) -> dict[str, Any]:
        """The coding as a coding file holds it."""
        out: dict[str, Any] = {
            "directions": list(self.directions),
            "periods": list(self.periods),
            "period_unit": self.period_unit,
            "order": list(self.order),
            "shifts": self.shifts,
            "shift_sign": self.shift_sign,
            "origin": list(self.origin),
            "screen_size_mm": list(self.screen_size_mm),
        }
        if self.offset is not None:
            out["offset"] = self.offset
        if self.amplitude is not None:
            out["amplitude"] = self.amplitude
        return out

    @classmethod
    def from_dict(cls, values: dict[str, Any], where: str = "coding") -> CaptureCoding:
        """The coding a coding file holds (one line naming ``where`` when it is not one)."""
        known = set(cls.__dataclass_fields__)
        unknown = sorted(set(values) - known)
        if unknown:
            raise GlshadeError(
                f"{where}: unknown key {unknown[0]} (known: {', '.join(sorted(known))})"
            )
        missing = [
            k for k in ("directions", "periods", "shifts", "screen_size_mm") if k not in values
        ]
        if missing:
            raise GlshadeError(f"{where}: missing {', '.join(missing)}")
        try:
            return cls(**values)
        except GlshadeError as error:
            raise GlshadeError(f"{where}: {error}") from None
        except (TypeError, ValueError) as error:
            raise GlshadeError(f"{where}: {error}") from None

    @classmethod
    def of_codec(cls, codec: FringeCodec) -> CaptureCoding:
        """glshade's own coding in these terms (its frame order, mm, sign +1, origin low)."""
        return cls(
            directions=codec.directions,
            periods=codec.periods_mm,
            shifts=codec.shifts,
            screen_size_mm=(2 * codec.screen_half_size_mm[0], 2 * codec.screen_half_size_mm[1]),
            offset=codec.offset,
            amplitude=codec.amplitude,
        )


@dataclass(frozen=True)
class Capture:
    """A recorded sequence: ``frames`` (F, H, W) as recorded, in the coding's order;
    ``black``, ``white``: the screen's black and white recorded alike (or None);
    ``peak_response``: the recorded value of the screen's white above black (None:
    worked out from the frames); ``scene``: the glshade scene that made it, if any;
    ``source``: where it came from; ``response``: the station's display response
    recorded with it (None: unknown),
    which :func:`glshade.capture.decode.decode_capture` applies unless told another."""

    frames: np.ndarray
    coding: CaptureCoding
    black: np.ndarray | None = None
    white: np.ndarray | None = None
    peak_response: float | None = None
    scene: Any = None
    source: str = ""
    response: Response | None = None
    extra: dict[str, Any] = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        frames = np.asarray(self.frames)
        if frames.ndim != 3:
            raise GlshadeError(
                f"{self.source or 'capture'}: frames must be (F, H, W), got {frames.shape}"
            )
        if frames.shape[0] != self.coding.frame_count:
            raise GlshadeError(
                f"{self.source or 'capture'}: {self.coding.frame_count} frames for its coding, "
                f"got {frames.shape[0]}"
            )
        for name in ("black", "white"):
            image = getattr(self, name)
            if image is not None and np.shape(image) != frames.shape[1:]:
                raise GlshadeError(
                    f"{self.source or 'capture'}: {name} must be {frames.shape[1:]}, got "
                    f"{np.shape(image)}"
                )

    @property
    def shape(self) -> tuple[int, int]:
        """The image size (H, W)."""
        return (int(self.frames.shape[1]), int(self.frames.shape[2]))
