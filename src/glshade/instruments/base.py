"""What an instrument is: the one interface every way of measuring a scene implements.

An instrument is what an inspection station does with the light the renderer computes:
the paper's binarised stripe edges (``paper``), phase-measuring deflectometry (``pmd``),
or a third party's. It is a plug-in, registered through the ``glshade.instruments`` entry
point group (:mod:`glshade.instruments.registry`), and everything outside it (``measure
--method``, sweeps, the optimiser's goals, the studies, the snapshot plugin, the Dask
workers) reaches it through this interface and never by its name:

- **settings**: :attr:`Instrument.settings_type`, a frozen dataclass whose fields are
  declared with :func:`glshade.params.param` under ``measure.<key>`` (unit, range,
  default, flag, docs): the command line's flags, ``--set measure.<key>``, the
  ``[measure]`` table of scene and sweep files and the docs come from it;
- **capture and analysis**: :meth:`Instrument.measure` (one scene), or
  :meth:`Instrument.measure_group` (the scenes of one geometry, sharing their
  defect-free analysis);
- **record**: :attr:`Instrument.record_type`, a :class:`~glshade.instruments.record.Record`
  whose columns (name, unit, range, meaning) are declared once; :attr:`Instrument.outputs`
  the ones a sweep table keeps;
- **status**: each record carries ``status``/``status_reason``;
  :meth:`Instrument.concerns` says which statuses make a column unreadable;
- **goals**: the record columns the optimiser may aim at (:class:`Goal`);
- **resources**: a worker's memory (:attr:`Instrument.worker_memory`), a geometry's check
  against the memory budget (:meth:`Instrument.budget_plan`).
- **views**: the maps and numbers it offers the interactive viewer
  (:meth:`Instrument.views`, :class:`InstrumentViews`).

Nothing here imports the renderer or an instrument: this module is the contract.
"""

from __future__ import annotations

import dataclasses
import json
from abc import ABC, abstractmethod
from collections.abc import Callable, Hashable, Iterator, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from glshade.errors import GlshadeError
from glshade.instruments.record import Record
from glshade.scene import Scene

if TYPE_CHECKING:
    from glshade.rendering import Renderer


@dataclass(frozen=True)
class Case:
    """One scene to measure and the key its caller knows it by (a sweep's case id, the
    study's point of its plan)."""

    key: Hashable
    scene: Scene


@dataclass(frozen=True)
class Measured:
    """One measured case: the case, the instrument's result, its record (the row of the
    tables), the seconds its trace took, and what the caller's ``extra`` hook made of it."""

    case: Case
    result: Any
    record: Record
    trace_s: float
    extra: Any = None


#: ``extra(case, result, view) -> anything``: per-case work beside the numbers
#: (thumbnails, overlays, images); it runs where the case is measured. ``view`` is what
#: the instrument offers of the case (the stripe metric's baseline and images, say).
Extra = Callable[[Case, Any, Any], Any]


@dataclass(frozen=True)
class BudgetPlan:
    """How one geometry is measured within the memory budget: the bytes of defect-free
    maps its analysis may keep, and the cases traced ahead of the analysis threads."""

    cache_bytes: int = 0
    ahead: int = 0


@dataclass(frozen=True)
class Goal:
    """One objective of ``glshade optimize --metric NAME``: the record ``column`` it
    reads, the ``method`` (instrument) that measures it, ``sense`` +1 when more is better
    (the worst case over a family is the least) or -1 when less is, whether it needs a
    sensor (a number of noise), ``whole`` when the column counts whole units (then points
    tie on it and ``tie_column`` breaks the ties, and near-optimal means equal), and
    ``label`` how it reads on a plot's axis (default: the column and its unit);
    ``strict``: any status but ok makes it unreadable (else the instrument's
    :meth:`Instrument.concerns`); ``value_key``, ``tolerance_key`` and ``digits``: how
    ``glshade optimize --json`` names and rounds its value and tolerance; ``quantity``:
    what its value is called in a line of text (else the column's name and the sense)."""

    name: str
    column: str
    method: str
    sense: int = 1
    needs_sensor: bool = False
    whole: bool = False
    tie_column: str | None = None
    label: str | None = None
    strict: bool = False
    value_key: str | None = None
    tolerance_key: str = "tolerance"
    digits: int | None = None
    quantity: str = ""


@dataclass(frozen=True)
class WorkerMemory:
    """A worker process's peak memory measuring this instrument's cases:
    ``base_mib + bytes_per_pixel × pixels`` of the frame."""

    base_mib: float
    bytes_per_pixel: float

    def mib(self, pixels: int) -> float:
        return self.base_mib + self.bytes_per_pixel * pixels / (1 << 20)


@dataclass(frozen=True)
class FileOption:
    """An output an instrument writes beside its numbers: ``glshade measure``'s ``flag``
    (``--maps DIR``). ``kind``: ``file`` (a regular file of one of ``suffixes``), ``dir``
    (a folder of files the instrument names) or ``choice`` (how another option writes:
    one of ``choices``, ``default`` when not given)."""

    flag: str
    metavar: str
    help: str
    kind: str = "dir"
    suffixes: tuple[str, ...] = ()
    choices: tuple[str, ...] = ()
    default: str | None = None

    @property
    def dest(self) -> str:
        """The argparse destination of its flag."""
        return "file_" + self.flag.lstrip("-").replace("-", "_")


@dataclass(frozen=True)
class ViewMap:
    """A map of a measured case, as one of an instrument's views shows it: ``values``
    (H, W, float, NaN where the case has none), on a scale from ``bottom`` to ``top`` in
    ``unit``, with ``caption`` its words and ``colours`` a matplotlib colour map's name."""

    values: np.ndarray
    bottom: float
    top: float
    unit: str
    caption: str
    colours: str = "viridis"


@dataclass(frozen=True)
class InstrumentView:
    """One map an instrument offers the viewer: ``name`` (``glshade view --set
    view=NAME``), ``label`` (the hover's word for its value), ``map_of(scene, result)``
    its map of a case (``scene`` as measured, ``result`` what :meth:`Instrument.measure`
    gave), and ``no_value`` what the hover says where the map has none."""

    name: str
    label: str
    map_of: Callable[[Scene, Any], ViewMap]
    no_value: str = "no value"

    def hover(self, shown: ViewMap, row: int, col: int) -> str:
        """The hover's words for pixel ``(row, col)`` of the map ``shown``."""
        value = shown.values[row, col]
        if not np.isfinite(value):
            return f"{self.label}: {self.no_value}"
        return f"{self.label} {value:.4g} {shown.unit}"


@dataclass(frozen=True)
class InstrumentViews:
    """What an instrument offers the interactive viewer: its ``views`` (in the view
    menu's order), measured on :meth:`Instrument.prepared`'s scene at ``size`` pixels
    across (at most the image's, the same field of view); ``label`` its name in the
    readout; ``readout(scene, result, missing)`` the readout's lines of a measured case,
    or with ``result`` None the same lines with ``missing`` for each number ("..." while
    measuring, "-" when refused); ``measurer(settings)``, where given, a function
    ``(renderer, scene) -> result`` that keeps what it may between cases (a defect-free
    analysis), else each case is :meth:`Instrument.measure`'s."""

    label: str
    views: tuple[InstrumentView, ...]
    readout: Callable[[Scene | None, Any, str], list[str]]
    size: int = 256
    measurer: Callable[[Any], Callable[[Renderer, Scene], Any]] | None = None


class Instrument(ABC):
    """An instrument (module doc). Subclasses set the class attributes and implement
    :meth:`measure` and :meth:`record`; every other method has a default that a simple
    instrument keeps. Instances hold no state: one is made per registry."""

    #: Its name: ``--method NAME``, ``method = "NAME"`` in a ``[measure]`` table.
    name: ClassVar[str]
    #: What it is, in words ("phase measuring").
    title: ClassVar[str]
    #: Its analysis's version: a case measured by another version is measured again.
    version: ClassVar[int] = 1
    #: Its settings: a frozen dataclass, each field declared with ``param("measure.KEY", ...)``.
    settings_type: ClassVar[type]
    #: Its record: the columns of its tables, each with its unit.
    record_type: ClassVar[type[Record]]
    #: The record's columns a sweep table keeps (its measured and closed-form numbers).
    outputs: ClassVar[tuple[str, ...]]
    #: The units in which the snapshot plugin compares its record's measured columns, each
    #: with the field of :class:`glshade.snapshot.tolerance.Tolerances` that bounds them.
    compared_units: ClassVar[dict[str, str]] = {}
    #: What makes its numbers unreadable, in words (a sweep's summary says it).
    unreadable_words: ClassVar[str] = "the dent unreadable"
    #: A worker's peak memory for it.
    worker_memory: ClassVar[WorkerMemory] = WorkerMemory(256, 512)
    #: The optimiser's objectives it offers.
    goals: ClassVar[tuple[Goal, ...]] = ()
    #: Measured for a snapshot of any scene (True), or only where the scene's emitter is
    #: measured by it.
    always_snapshot: ClassVar[bool] = False
    #: What it writes beside its numbers when asked (``glshade measure``'s flags).
    file_options: ClassVar[tuple[FileOption, ...]] = ()

    # ------------------------------------------------------------------ settings
    def settings(self, **values: Any) -> Any:
        """Its settings of these values (the others their defaults), each checked against
        its declaration: a bad value is one line naming ``measure.KEY``."""
        return self.settings_type(**values)

    def identity(self, settings: Any) -> dict[str, Any]:
        """What, besides the scene, makes a case's identity (its id's hash)."""
        return {"method": self.name, self.name: _plain(settings), self.version_key: self.version}

    @property
    def version_key(self) -> str:
        """The manifest's key of :attr:`version`."""
        return f"{self.name}_version"

    # ------------------------------------------------------------------ scenes
    def prepared(self, scene: Scene) -> Scene:
        """``scene`` as this instrument measures it: where its emitter is measured by
        another instrument, the first registered emitter measured by this one takes its
        place (distance and size kept): phase measuring shows its fringe sequence where
        the scene had stripes."""
        if scene.active.emitter.measured_by == self.name:
            return scene
        from glshade.components.registry import registry

        for emitter in registry().components("emitter"):
            if getattr(emitter, "measured_by", None) == self.name:
                return scene.updated(emitter={"kind": emitter.name})
        raise GlshadeError(f"method {self.name!r}: no registered emitter is measured by it")

    def check_case(self, scene: Scene, settings: Any) -> None:
        """Refuse, in one line and before anything is rendered, a scene this instrument
        cannot measure with these settings (default: one whose emitter another measures)."""
        measured_by = scene.active.emitter.measured_by
        if self.prepared(scene) is not scene:
            raise GlshadeError(
                f"emitter.kind = {scene.emitter.kind!r} is measured by {measured_by}, not by "
                f'{self.name} (set [measure] method = "{measured_by}")'
            )

    def geometry_key(self, scene: Scene, settings: Any) -> str:
        """Scenes with equal keys share their defect-free analysis (default: the scene
        without its defect)."""
        return json.dumps(scene.without_defect().to_dict(), sort_keys=True, default=str)

    # ------------------------------------------------------------------ measuring
    @abstractmethod
    def measure(self, renderer: Renderer, scene: Scene, settings: Any) -> Any:
        """Capture and analyse one scene: its result (what :meth:`record` reads)."""

    @abstractmethod
    def record(self, scene: Scene, result: Any, trace_s: float = 0.0) -> Record:
        """The row of ``result``: an instance of :attr:`record_type`."""

    def check_files(self, files: dict[str, Any], scene: Scene, inputs: Sequence[Any]) -> None:
        """Refuse, before any work, a folder option of :attr:`file_options` it cannot write
        (``files``: flag -> value given; ``inputs``: the run's input files). A ``file``
        option is checked by the caller (a regular file of its suffixes)."""
        return None

    def measure_files(
        self, renderer: Renderer, scene: Scene, settings: Any, files: dict[str, Any]
    ) -> Any:
        """:meth:`measure`, writing what a ``file`` option asks for that only the
        measurement holds (a figure of its intermediate images); default: :meth:`measure`."""
        return self.measure(renderer, scene, settings)

    def write_files(self, files: dict[str, Any], scene: Scene, result: Any) -> list[str]:
        """Write what the options ask for after the measurement succeeded; what was
        written, one line each (default: the ``file`` options given, which
        :meth:`measure_files` wrote)."""
        return [
            str(files[option.flag])
            for option in self.file_options
            if option.kind == "file" and files.get(option.flag) is not None
        ]

    def warnings(self, scene: Scene, result: Any) -> list[str]:
        """Lines to warn the user about a measured result (a washed-out picture)."""
        return []

    def budget_plan(
        self,
        scene: Scene,
        settings: Any,
        budget_bytes: int,
        threads: int = 1,
        pooled: bool = False,
    ) -> BudgetPlan:
        """The memory check of a geometry before it is traced: a one-line GlshadeError
        where its buffers and analysis exceed ``budget_bytes``, else its plan."""
        return BudgetPlan()

    def measure_group(
        self,
        renderer: Renderer,
        group: Sequence[Case],
        settings: Any,
        pool: Executor | None,
        extra: Extra | None,
        plan: BudgetPlan,
    ) -> Iterator[Measured]:
        """The cases of one geometry, in order (default: each measured alone; ``extra``
        gets ``None`` as its view)."""
        for case in group:
            result = self.measure(renderer, case.scene, settings)
            made = extra(case, result, None) if extra is not None else None
            yield Measured(case, result, self.record(case.scene, result), 0.0, made)

    # ------------------------------------------------------------------ reading numbers
    def concerns(self, status: str, column: str) -> bool:
        """True when a record of ``status`` cannot give ``column`` (default: any status
        but ok)."""
        return status != "ok"

    def summary_lines(self, scene: Scene, record: Record) -> list[str]:
        """``glshade measure``'s lines for a record: each measured column with its unit,
        marked where its status makes it unreadable."""
        lines = [f"Scene: {scene.title()}"]
        for column in record.columns():
            if column.role != "measured" or column.name in ("status", "status_reason"):
                continue
            value = getattr(record, column.name)
            shown = "—" if value is None else f"{value:.6g}" if _real(value) else str(value)
            unit = f" {column.unit}" if column.unit and value is not None else ""
            mark = f"  ({record.status})" if self.concerns(record.status, column.name) else ""
            lines.append(f"{column.name}: {shown}{unit}{mark}")
        reason = getattr(record, "status_reason", "")
        lines.append(f"status: {record.status}{f' ({reason})' if reason else ''}")
        return lines

    def image(self, case: Case, result: Any, view: Any) -> np.ndarray | None:
        """The case's picture as its camera records it (a sweep's ``--images``; float in
        [0, 1] or the sensor's units), from what :meth:`measure_group` gave ``extra`` as
        ``view``; None: the instrument has none."""
        return None

    def column_unit(self, column: str) -> str:
        """The unit of one of its record's columns."""
        return next(c.unit for c in self.record_type.columns() if c.name == column)

    # ------------------------------------------------------------------ viewer
    def views(self) -> InstrumentViews | None:
        """What it offers the interactive viewer (:class:`InstrumentViews`); default none."""
        return None


def _plain(settings: Any) -> dict[str, Any]:
    """Settings as plain values (a dataclass's fields, in order)."""
    return dataclasses.asdict(settings)


def _real(value: Any) -> bool:
    return isinstance(value, float)
