"""Phase-measuring deflectometry (``--method pmd``): the fringe sequence shown on the
screen, recorded, decoded into screen points, and the dent's slopes and heights
reconstructed from them, as an industrial PMD station does (docs/pmd.md)."""

from __future__ import annotations

import json
from collections.abc import Iterator, Sequence
from concurrent.futures import Executor
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from glshade.instruments.base import (
    BudgetPlan,
    Case,
    Extra,
    FileOption,
    Goal,
    Instrument,
    InstrumentViews,
    Measured,
    WorkerMemory,
)
from glshade.instruments.pmd.baseline import PmdBaseline, pmd_baseline
from glshade.instruments.pmd.model import defect_free, station_model
from glshade.instruments.pmd.settings import PMD_VERSION, PmdSettings, check_scene
from glshade.instruments.pmd.station import PmdResult, measure_pmd_scene
from glshade.instruments.pmd.status import pmd_concerns
from glshade.instruments.record import PMD_OUTPUT_NAMES, PmdMeasurement
from glshade.scene import Scene

if TYPE_CHECKING:
    from glshade.rendering import Renderer


@dataclass(frozen=True)
class PmdView:
    """What an ``extra`` hook of a phase-measured case may look at: its defect-free
    analysis (the result carries the case's maps)."""

    baseline: PmdBaseline


def _goal(column: str, sense: int = 1, needs_sensor: bool = False) -> Goal:
    # a viewpoint whose dent cannot be read is no place for the station, however low its
    # noise: any status but ok makes a phase-measuring goal unreadable
    return Goal(column, column, "pmd", sense, needs_sensor, strict=True)


class PhaseInstrument(Instrument):
    """Phase-measuring deflectometry (module doc)."""

    name: ClassVar[str] = "pmd"
    title: ClassVar[str] = "phase measuring"
    version: ClassVar[int] = PMD_VERSION
    settings_type: ClassVar[type] = PmdSettings
    record_type = PmdMeasurement
    outputs: ClassVar[tuple[str, ...]] = PMD_OUTPUT_NAMES
    compared_units: ClassVar[dict[str, str]] = {"mm": "pmd_mm", "µm": "pmd_um"}
    unreadable_words: ClassVar[str] = (
        "fringes averaged out, the dent at an edge or out of view, the exposure, or under "
        "the noise floor"
    )
    # fitted above the peak RSS of one LocalCluster worker measuring four cases (the
    # station's 4 periods x 4 shifts x 2 directions): 356, 1390 and 4424 MiB at 256²,
    # 1024² and 2048²
    worker_memory: ClassVar[WorkerMemory] = WorkerMemory(base_mib=384, bytes_per_pixel=1024)
    file_options: ClassVar[tuple[FileOption, ...]] = (
        FileOption(
            "--maps", "DIR",
            "pmd: write the maps behind the numbers (decoded.npy, exact.npy, modulation.npy, "
            "modulation_share.npy, wrapped_phase.npy, error_mm.npy, slopes.npy, height_um.npy, "
            "the defect-free and noise-twin decodes, ...; docs/pmd.md) and figures",
        ),
        FileOption(
            "--frames", "DIR",
            "pmd: write the recorded sequence, the recorded white and manifest.json (all an "
            "external decoder needs); an earlier run's frames there are replaced",
        ),
        FileOption(
            "--frame-format", "FORMAT", "pmd --frames: 16-bit PNG (default) or 32-bit float TIFF",
            kind="choice", choices=("png", "tif"), default="png",
        ),
    )  # fmt: skip
    goals: ClassVar[tuple[Goal, ...]] = (
        _goal("pmd_snr", needs_sensor=True),
        _goal("pmd_shift_mm"),
        _goal("pmd_depth_um"),
        _goal("pmd_slope_urad"),
        _goal("pmd_noise_mm", sense=-1, needs_sensor=True),
    )

    def check_case(self, scene: Scene, settings: Any) -> None:
        check_scene(scene)

    def geometry_key(self, scene: Scene, settings: Any) -> str:
        """Dents at one place share the defect-free analysis, whatever their depth and
        width (:func:`~glshade.instruments.pmd.model.defect_free`)."""
        return json.dumps(defect_free(scene).to_dict(), sort_keys=True, default=str)

    def measure(self, renderer: Renderer, scene: Scene, settings: Any) -> PmdResult:
        return measure_pmd_scene(renderer, scene, settings)

    def measure_files(
        self, renderer: Renderer, scene: Scene, settings: Any, files: dict[str, Any]
    ) -> PmdResult:
        """:meth:`measure`, every recorded frame kept where ``--frames`` asks for them."""
        keep = files.get("--frames") is not None
        return measure_pmd_scene(renderer, scene, settings, keep_frames=keep)

    def record(self, scene: Scene, result: Any, trace_s: float = 0.0) -> PmdMeasurement:
        return PmdMeasurement.of(scene, result)

    def budget_plan(
        self,
        scene: Scene,
        settings: Any,
        budget_bytes: int,
        threads: int = 1,
        pooled: bool = False,
    ) -> BudgetPlan:
        from glshade.instruments.memory import check_pmd

        check_pmd(scene, budget_bytes, results=1)
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
        """One geometry measured as a PMD station measures it, its defect-free analysis
        once; ``extra`` gets a :class:`PmdView`."""
        baseline = pmd_baseline(renderer, station_model(group[0].scene), settings)
        windows = [station_model(case.scene).window for case in group]
        baseline.twin_over(renderer, np.logical_or.reduce(windows))  # once for the group
        for case in group:
            result = measure_pmd_scene(renderer, case.scene, settings, baseline)
            made = extra(case, result, PmdView(baseline)) if extra is not None else None
            trace_s = result.seconds.get("render", 0.0)
            yield Measured(case, result, PmdMeasurement.of(case.scene, result), trace_s, made)

    def image(self, case: Case, result: Any, view: Any) -> Any:
        """The first recorded frame (the finest fringes of the first direction, shift 0),
        as the camera records it."""
        return result.maps.recorded[0]

    def check_files(self, files: dict[str, Any], scene: Scene, inputs: Sequence[Any]) -> None:
        from glshade.instruments.pmd.files import check_output_dir

        for flag in ("--maps", "--frames"):
            if files.get(flag) is not None:
                check_output_dir(files[flag], flag, tuple(inputs))

    def write_files(self, files: dict[str, Any], scene: Scene, result: Any) -> list[str]:
        from glshade.instruments.pmd.files import write_frames, write_maps

        written = []
        if files.get("--frames") is not None:
            write_frames(files["--frames"], scene, result, files.get("--frame-format") or "png")
            written.append(f"{files['--frames']}/ (--frames)")
        if files.get("--maps") is not None:
            write_maps(files["--maps"], scene, result)
            written.append(f"{files['--maps']}/ (--maps)")
        return written

    def summary_lines(self, scene: Scene, record: Any) -> list[str]:
        from glshade.instruments.pmd.summary import summary_lines

        return summary_lines(scene, record)

    def concerns(self, status: str, column: str) -> bool:
        return pmd_concerns(status, column)

    def views(self) -> InstrumentViews:
        """The viewer's PMD views: the phase, modulation, error and slope maps
        (:mod:`glshade.instruments.pmd.views`)."""
        from glshade.instruments.pmd.views import pmd_views

        return pmd_views()
