"""The paper's instrument: the stripe images with and without the dent binarised, their
contours compared, the largest shift the dent's visibility (``--method paper``).

- :mod:`.single`: one scene (its emitter maps, its phase images, its baseline);
- :mod:`.group`: the scenes of one geometry sharing their defect-free analysis.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator, Sequence
from concurrent.futures import Executor
from typing import TYPE_CHECKING, Any, ClassVar

from glshade.errors import GlshadeError
from glshade.instruments.base import (
    BudgetPlan,
    Case,
    Extra,
    FileOption,
    Goal,
    Instrument,
    Measured,
    WorkerMemory,
)
from glshade.instruments.record import OUTPUT_NAMES, Measurement
from glshade.metrics.status import concerns
from glshade.metrics.visibility import METRIC_VERSION, MetricSettings, Visibility
from glshade.scene import Scene

if TYPE_CHECKING:
    from glshade.rendering import Renderer

#: The columns the stripe metric's statuses can make unreadable.
READ_COLUMNS = ("visibility_px", "visibility_continuous_px", "deflection_px")


class StripeInstrument(Instrument):
    """The paper's stripe-edge metric (module doc)."""

    name: ClassVar[str] = "paper"
    title: ClassVar[str] = "the paper's stripe metric"
    version: ClassVar[int] = METRIC_VERSION
    settings_type: ClassVar[type] = MetricSettings
    record_type = Measurement
    outputs: ClassVar[tuple[str, ...]] = OUTPUT_NAMES
    compared_units: ClassVar[dict[str, str]] = {"px": "visibility_px"}
    unreadable_words: ClassVar[str] = (
        "stripes unresolved, the dent at an edge or out of view, or under the noise floor"
    )
    # fitted above the peak RSS of one LocalCluster worker measuring four cases (flat and
    # sphere, two elevations) on llvmpipe: 230, 372 and 889 MiB at 256², 1024² and 2048²
    worker_memory: ClassVar[WorkerMemory] = WorkerMemory(base_mib=224, bytes_per_pixel=176)
    goals: ClassVar[tuple[Goal, ...]] = (
        Goal(
            "paper", "visibility_px", "paper", whole=True,
            tie_column="visibility_continuous_px", label="visibility (paper), px",
            value_key="visibility_px", tolerance_key="tolerance_px", digits=4,
            quantity="visibility",
        ),
        Goal(
            "continuous", "visibility_continuous_px", "paper",
            label="visibility (continuous), px", value_key="visibility_px",
            tolerance_key="tolerance_px", digits=4, quantity="visibility",
        ),
    )  # fmt: skip
    always_snapshot: ClassVar[bool] = True
    file_options: ClassVar[tuple[FileOption, ...]] = (
        FileOption(
            "--overlay", "PNG", "also write the Fig. 9 contour overlay at the best phase",
            kind="file", suffixes=(".png",),
        ),
    )  # fmt: skip

    def identity(self, settings: Any) -> dict[str, Any]:
        # exactly what it was before there were other instruments, so old sweeps resume
        return {"metric": dataclasses.asdict(settings), "metric_version": self.version}

    @property
    def version_key(self) -> str:
        return "metric_version"

    def check_case(self, scene: Scene, settings: Any) -> None:
        super().check_case(scene, settings)
        # a step longer than the period is refused before rendering
        settings.phases(scene.active.emitter.pattern(scene).period_mm)

    def geometry_key(self, scene: Scene, settings: Any) -> str:
        from glshade.instruments.stripes.single import map_baseline_key, shades_from_map

        if shades_from_map(scene):
            return map_baseline_key(scene)
        return super().geometry_key(scene, settings)

    def measure(self, renderer: Renderer, scene: Scene, settings: Any) -> Visibility:
        from glshade.instruments.stripes.single import measure_scene

        return measure_scene(renderer, scene, settings)

    def measure_files(
        self, renderer: Renderer, scene: Scene, settings: Any, files: dict[str, Any]
    ) -> Visibility:
        from glshade.instruments.stripes.single import measure_scene

        return measure_scene(renderer, scene, settings, overlay=files.get("--overlay"))

    def warnings(self, scene: Scene, result: Any) -> list[str]:
        from glshade.metrics.status import contrast_warning

        low = contrast_warning(result.stripe_contrast, scene.active.dimming(scene))
        return [low] if low else []

    def summary_lines(self, scene: Scene, record: Any) -> list[str]:
        from glshade.instruments.stripes.summary import summary_lines

        return summary_lines(scene, record)

    def record(self, scene: Scene, result: Any, trace_s: float = 0.0) -> Measurement:
        if not isinstance(result, Visibility):
            raise GlshadeError(f"result: a Visibility, got {type(result).__name__}")
        return Measurement.of(scene, result, trace_s)

    def budget_plan(
        self,
        scene: Scene,
        settings: Any,
        budget_bytes: int,
        threads: int = 1,
        pooled: bool = False,
    ) -> BudgetPlan:
        from glshade.instruments.stripes import group

        return group.budget_plan(scene, settings, budget_bytes, threads, pooled)

    def measure_group(
        self,
        renderer: Renderer,
        group: Sequence[Case],
        settings: Any,
        pool: Executor | None,
        extra: Extra | None,
        plan: BudgetPlan,
    ) -> Iterator[Measured]:
        from glshade.instruments.stripes import group as groups

        return groups.measure_group(renderer, group, settings, pool, extra, plan)

    def image(self, case: Case, result: Any, view: Any) -> Any:
        """The image at the case's best phase (``view``: its
        :class:`~glshade.instruments.stripes.group.CaseView`)."""
        return view.best_image(case.scene, result)

    def concerns(self, status: str, column: str) -> bool:
        return column in READ_COLUMNS and concerns(status, column)
