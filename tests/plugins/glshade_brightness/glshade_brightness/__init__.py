"""A toy third-party glshade instrument: the largest change in image brightness a dent
makes (a camera that compares two photographs, with no stripe edges and no decoding).

Installed as a package, it is found through its entry point (``pyproject.toml``)::

    [project.entry-points."glshade.instruments"]
    brightness = "glshade_brightness:Brightness"

and is then measured as ``--method brightness``, swept with ``[measure] method =
"brightness"``, optimised with ``--metric brightness_change`` and snapshot-tested, all
through glshade's instrument interface (:class:`glshade.instruments.base.Instrument`):
its settings (one, declared with :func:`glshade.params.param` under ``measure.``), its
record (three numbers and a status, each column with its unit) and its measurement.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from glshade.instruments.base import Goal, Instrument, WorkerMemory
from glshade.instruments.record import Record, column
from glshade.params import Table, param

__all__ = ["Brightness", "BrightnessRecord", "BrightnessSettings"]


@dataclass(frozen=True)
class BrightnessSettings(Table):
    """How the change is read: below ``floor`` (a share of the emitter's peak) it is none."""

    table = "measure"

    floor: float = param(
        "measure.floor", "", 1e-4,
        "brightness: a change below this share of the emitter's peak is no change",
        lo=0.0, hi=1.0, flag="--floor",
    )  # fmt: skip


@dataclass(frozen=True)
class BrightnessRecord(Record):
    """The largest brightness change and where the dent changes the image."""

    record = True

    brightness_change: float | None = column(
        "", "the largest change of a pixel's brightness the dent makes, a share of the "
        "emitter's peak", low=0.0,
    )  # fmt: skip
    changed_pixels: int = column(
        "count", "pixels whose brightness the dent changes by more than the floor"
    )
    status: str = column(
        "", "ok, or outside: the dent changes no pixel by more than the floor",
        choices=("ok", "outside"),
    )  # fmt: skip
    status_reason: str = column("", "why the number cannot be read (empty when ok)")
    render_s: float = column("s", "seconds the two renders took", "timing")


@dataclass(frozen=True)
class BrightnessResult:
    """The two images' difference, read."""

    change: float
    changed: int
    seconds: float


class Brightness(Instrument):
    """The largest brightness change (module doc)."""

    name: ClassVar[str] = "brightness"
    title: ClassVar[str] = "the largest brightness change"
    settings_type: ClassVar[type] = BrightnessSettings
    record_type = BrightnessRecord
    outputs: ClassVar[tuple[str, ...]] = ("brightness_change", "changed_pixels", "status")
    compared_units: ClassVar[dict[str, str]] = {"": "image"}
    unreadable_words: ClassVar[str] = "the dent changes no pixel's brightness"
    worker_memory: ClassVar[WorkerMemory] = WorkerMemory(base_mib=224, bytes_per_pixel=64)
    always_snapshot: ClassVar[bool] = True  # its numbers beside every snapshot
    goals: ClassVar[tuple[Goal, ...]] = (
        Goal("brightness_change", "brightness_change", "brightness"),
    )

    def check_case(self, scene: Any, settings: Any) -> None:
        """Any scene: the image is all this instrument reads."""

    def prepared(self, scene: Any) -> Any:
        return scene

    def measure(self, renderer: Any, scene: Any, settings: Any) -> BrightnessResult:
        import time

        start = time.perf_counter()
        bare = renderer.render(scene.without_defect()).image.astype(np.float64)
        dented = renderer.render(scene).image.astype(np.float64)
        difference = np.abs(dented - bare)
        return BrightnessResult(
            float(difference.max()),
            int((difference > settings.floor).sum()),
            time.perf_counter() - start,
        )

    def record(self, scene: Any, result: Any, trace_s: float = 0.0) -> BrightnessRecord:
        seen = result.changed > 0
        return BrightnessRecord(
            brightness_change=round(result.change, 6),
            changed_pixels=result.changed,
            status="ok" if seen else "outside",
            status_reason="" if seen else "the dent changes no pixel by more than measure.floor",
            render_s=round(result.seconds, 4),
        )
