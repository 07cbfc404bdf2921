"""The viewer's state without a window: the scene, the traced maps, the metrics in a
worker thread, the instrument views' cases in a station of their own, and which work a
change calls for (tested without a display)."""

from __future__ import annotations

import threading
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from concurrent.futures import wait as wait_for
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from glshade.app.viewer.colourbar import ColourScale, colour_index, colour_lut
from glshade.app.viewer.controls import apply_setting, geometry_key
from glshade.app.viewer.instrument_view import (
    STRIPE_VIEWS,
    InstrumentCases,
    OfferedView,
    case_lines,
    first_views,
    instrument_views,
    view_hover,
    view_rgba,
)
from glshade.errors import GlshadeError, SceneError
from glshade.instruments.stripes.single import judged, map_baseline
from glshade.metrics import contours
from glshade.metrics import visibility as vis
from glshade.metrics.status import concerns
from glshade.scene import PAPER_SURFACES, Scene, paper_scene

if TYPE_CHECKING:
    from glshade.instruments.registry import Instruments
    from glshade.instruments.table import MeasureTable
    from glshade.rendering import Renderer


@dataclass
class Readout:
    """The panel's numbers, the latest the worker finished: the paper's comparison at the
    current phase, and the whole case measured by the same pipeline as
    ``glshade paper`` and ``glshade measure``."""

    at_phase_px: float | None = None  # the paper's metric at the phase shown
    at_phase_islands: int | None = None
    visibility_px: float | None = None  # the paper's metric over the phase sweep
    best_phase_mm: float | None = None
    continuous_px: float | None = None  # its continuous limit
    deflection_px: float | None = None
    folded: bool | None = None
    islands: int | None = None
    phase_for: tuple | None = None
    error: str | None = None  # why this geometry cannot be measured
    status: str | None = None  # whether the numbers can be read (glshade.metrics.status)
    status_reason: str = ""


def readout_lines(r: Readout) -> list[str]:
    """The panel's readout as text ("..." while the worker is still measuring, "-" and
    the reason when the metric refuses the scene)."""

    def px(value, fmt):
        if value is None:
            return "-" if r.error is not None else "..."
        return f"{value:{fmt}} px"

    def flag(column: str) -> str:
        return f" [{r.status}: not measurable]" if concerns(r.status or "ok", column) else ""

    best = "" if r.best_phase_mm is None else f" (phase {r.best_phase_mm:g} mm)"
    lines = [
        f"visibility, this phase: {px(r.at_phase_px, 'g')}{flag('visibility_px')}",
        f"visibility, best phase: {px(r.visibility_px, 'g')}{best}{flag('visibility_px')}",
        f"continuous limit: {px(r.continuous_px, '.2f')}{flag('visibility_continuous_px')}",
        f"deflection: {px(r.deflection_px, '.2f')}{flag('deflection_px')}",
    ]
    if r.status is None:  # a line always, so the panel's height does not change
        lines.append("status: -" if r.error is not None else "status: ...")
    else:
        lines.append(f"status: {r.status}" + (f": {r.status_reason}" if r.status_reason else ""))
    if r.error is not None:
        lines.append(f"not measured: {r.error}")
    return lines


def _attempt(key, work):
    """A worker job: ``(key, result, None)``, or ``(key, None, reason)`` when the metric
    refuses the scene (e.g. a stripe period shorter than the phase step): the viewer shows
    the reason instead of dying on it."""
    try:
        return key, work(), None
    except GlshadeError as exc:
        return key, None, " ".join(str(exc).split())


class _Once:
    """A value made on first use by whichever thread asks first (the others wait)."""

    def __init__(self, make) -> None:
        self._make, self._lock, self._value = make, threading.Lock(), None

    def get(self):
        with self._lock:
            if self._value is None:
                self._value = self._make()
            return self._value


@dataclass
class ViewerModel:
    """Everything the viewer knows, without a window: the scene, the traced maps, the
    metrics, the views the instruments of ``instruments`` (default: the registry) offer
    and their latest case, and which work a change calls for."""

    scene: Scene
    view: str = "image"
    animate: bool = False
    phase_speed_periods: float = 0.5  # periods per second when animating
    settings: vis.MetricSettings = field(default_factory=vis.MetricSettings)  # as glshade paper
    v0: np.ndarray | None = None  # traced emitter maps (v only), defect-free and defect
    v1: np.ndarray | None = None
    uv1: np.ndarray | None = None
    displacement: np.ndarray | None = None
    readout: Readout = field(default_factory=Readout)
    traced_for: Scene | None = None
    traces: int = 0
    reshades: int = 0
    scene_passes: int = 0  # the window's display pass run (not per frame: on a change)
    refused: str = ""
    instruments: Instruments | None = None  # whose views it offers (None: the registry's)
    make_renderer: Callable[[], Renderer] | None = None  # the station's (None: headless GL)
    case_size: int | None = None  # an instrument view's case's pixels across (at most)
    measure_table: MeasureTable | None = None  # the scene file's [measure]: its settings
    cases: InstrumentCases = field(init=False)  # the instrument views' cases
    _baseline: _Once | None = None
    _pool: ThreadPoolExecutor | None = None
    _case_job: Future | None = None
    _phase_job: Future | None = None
    _case_done: bool = False
    _offered: dict[str, OfferedView] | None = None

    def __post_init__(self) -> None:
        self.cases = InstrumentCases(self.make_renderer, self.measure_table)
        if self.measure_table is not None:  # the stripe views' settings, where it has them
            from glshade.instruments.registry import instruments

            stripes = (self.instruments or instruments()).of_settings(self.settings).name
            self.settings = replace(self.settings, **self.measure_table.for_method(stripes))

    # ---------------------------------------------------------------- edits
    def set(self, name: str, value, slider: bool = False) -> bool:
        """Apply one control; False (no change, and ``refused`` says why, in the words of
        ``render``'s error) when the value is rejected."""
        try:
            self.scene = apply_setting(self.scene, name, value, slider)
        except (SceneError, GlshadeError) as exc:
            self.refused = f"refused: {exc}"
            return False
        self.refused = ""
        return True

    def set_value(self, path: str, value) -> bool:
        """Set any parameter by its dotted path (a formula, a file path), validated as
        ``render`` validates it; False and ``refused`` on a refusal."""
        try:
            self.scene = self.scene.with_value(path, value)
        except GlshadeError as exc:
            self.refused = f"refused: {exc}"
            return False
        self.refused = ""
        return True

    def reset(self) -> None:
        cam = self.scene.camera
        kind = self.scene.surface.kind
        scene = (
            paper_scene(kind)
            if kind in PAPER_SURFACES
            else paper_scene().with_value("surface.kind", kind)
        )
        self.scene = scene.with_size(cam.width)
        self.view, self.animate = "image", False

    def advance(self, seconds: float) -> None:
        if self.animate:
            period = self.scene.active.emitter.pattern(self.scene).period_mm
            self.scene = self.scene.with_phase(
                (self.scene.emitter.phase + self.phase_speed_periods * period * seconds) % period
            )

    @property
    def needs_trace(self) -> bool:
        return self.traced_for != geometry_key(self.scene)

    @property
    def shades_from_uv(self) -> bool:
        """The picture is a function of the uv map (mirror, one ray per pixel)."""
        from glshade.instruments.stripes.single import shades_from_map

        return shades_from_map(self.scene)

    def traced(self, uv_defect: np.ndarray, v_normal: np.ndarray) -> None:
        self.uv1 = uv_defect
        self.v1 = np.ascontiguousarray(uv_defect[..., 1])
        self.v0 = v_normal
        self.traced_for = geometry_key(self.scene)
        self.traces += 1
        self.displacement = None
        self.readout = Readout()
        v0, scene, settings = self.v0, self.scene, self.settings
        self._baseline = _Once(lambda: map_baseline(scene, v0, settings))
        self._case_done = False

    def baseline(self) -> vis.Baseline | None:
        """The defect-free analysis of the traced geometry (made once, in whichever
        thread asks first)."""
        return self._baseline.get() if self._baseline is not None else None

    # ---------------------------------------------------------------- pictures
    def traced_map(self) -> np.ndarray:
        """The scene's traced emitter map ``v`` (an error before the first trace)."""
        if self.v1 is None:
            raise GlshadeError("the viewer has not traced the scene yet")
        return self.v1

    def overlay_rgba(self) -> np.ndarray:
        """Fig. 9 colours on the kept columns, as the metric sees them (normal blue, defect
        red, both magenta, islands orange); the columns cut off are dark grey."""
        v1 = self.traced_map()
        h, w = v1.shape
        rgba = np.zeros((h, w, 4), np.uint8)
        rgba[..., :3] = 40
        rgba[..., 3] = 255
        try:
            baseline = self.baseline()
        except GlshadeError:  # the metric refuses this scene (the readout says why)
            baseline = None
        if baseline is not None and baseline.half_width_mm is not None:
            normal, defect = baseline.stripes_at(v1, self.scene.emitter.phase)
            rgba[:, baseline.columns, :3] = contours.overlay_rgb(normal, defect)
        return rgba

    def displacement_rgba(self) -> tuple[np.ndarray, float]:
        """The displacement (deflection) as a colour map (the colour bar's, from 0 to the
        largest displacement), and that top end of the scale (px)."""
        h, w = self.traced_map().shape
        rgba = np.zeros((h, w, 4), np.uint8)
        rgba[..., 3] = 255
        if self.displacement is None:
            return rgba, 0.0
        top = float(np.nanmax(self.displacement)) if np.isfinite(self.displacement).any() else 0.0
        lut = colour_lut()
        finite = np.isfinite(self.displacement)
        index = colour_index(np.where(finite, self.displacement, 0.0), top)
        rgba[..., :3] = np.where(finite[..., None], lut[index], 0)
        return rgba, top

    def instrument_rgba(self) -> tuple[np.ndarray, ColourScale]:
        """The instrument view's map as a colour map at the image's size, and its scale
        (the latest case the station finished; dark, captioned, before the first)."""
        shape = self.traced_map().shape
        offered = self.instrument_view
        case = self.cases.of(offered)
        if offered is None:
            raise GlshadeError(f"view {self.view!r} is not an instrument's")
        if case.result is None or case.scene is None:
            rgba = np.zeros((*shape, 4), np.uint8)
            rgba[..., 3] = 255
            doing = "not measured (see the readout)" if case.error else "computing..."
            return rgba, ColourScale(0.0, 0.0, "", f"{offered.instrument.title}: {doing}")
        return view_rgba(offered.view, case.scene, case.result, shape)

    def hover(self, col: int, row: int) -> str:
        if self.uv1 is None or not (0 <= row < self.uv1.shape[0] and 0 <= col < self.uv1.shape[1]):
            return ""
        u, v = self.uv1[row, col]
        offered = self.instrument_view
        case = self.cases.of(offered)
        if offered is not None and case.result is not None and case.scene is not None:
            shape = self.uv1.shape[:2]
            value = view_hover(offered.view, case.scene, case.result, row, col, shape)
            return f"pixel ({col}, {row}): {value}"
        if not np.isfinite(v):
            return f"pixel ({col}, {row}): no emitter hit"
        text = f"pixel ({col}, {row}): u {u:.3f} mm, v {v:.3f} mm"
        if self.displacement is not None and np.isfinite(self.displacement[row, col]):
            text += f", displacement {self.displacement[row, col]:.2f} px"
        return text

    def readout_text(self) -> list[str]:
        """The panel's readout for the view: the instrument's numbers in an instrument
        view, the paper's otherwise."""
        offered = self.instrument_view
        if offered is None:
            return readout_lines(self.readout)
        case = self.cases.of(offered)
        shown = case.scene
        size = shown.camera.width if shown is not None else self._case_size(offered)
        return case_lines(offered.offer, case, self.cases.job is not None, size)

    @property
    def width(self) -> int:
        return self.scene.camera.width

    # ---------------------------------------------------------------- views
    def offered_views(self) -> dict[str, OfferedView]:
        """The views the instruments offer, by name (asked once)."""
        if self._offered is None:
            self._offered = instrument_views(self.instruments)
        return self._offered

    def view_names(self) -> tuple[str, ...]:
        """The view menu: the viewer's own views, then the instruments'."""
        return STRIPE_VIEWS + tuple(self.offered_views())

    def first_views(self) -> list[OfferedView]:
        """Each instrument's first view (the P key shows the first of them)."""
        return first_views(self.offered_views())

    def toggle_instrument_view(self) -> None:
        """The P key: the first instrument view, or from any instrument view the image."""
        firsts = self.first_views()
        if self.instrument_view is not None:
            self.view = "image"
        elif firsts:
            self.view = firsts[0].view.name

    @property
    def instrument_view(self) -> OfferedView | None:
        """The view shown, where an instrument offers it; None in the viewer's own."""
        return self.offered_views().get(self.view)

    def _case_size(self, offered: OfferedView) -> int:
        size = self.case_size if self.case_size is not None else offered.offer.size
        return min(size, self.width)

    # ---------------------------------------------------------------- metrics
    @property
    def metrics_pending(self) -> bool:
        """A job is in the worker (the window polls for it instead of sleeping)."""
        jobs = (self._case_job, self._phase_job, self.cases.job)
        return any(job is not None for job in jobs)

    def collect_metrics(self) -> bool:
        """Take whatever the workers finished (call before :meth:`start_metrics`); True
        when something was taken (the panel has news to show)."""
        taken = self.cases.collect()
        if self._case_job is not None and self._case_job.done():
            trace, result, error = self._case_job.result()
            self._case_job, taken = None, True
            if trace == self.traces and error is not None:
                self.readout.error = error
                self._case_done = True
            elif trace == self.traces:
                r = self.readout
                r.visibility_px, r.best_phase_mm = result.visibility_px, result.best_phase_mm
                r.continuous_px, r.deflection_px = (
                    result.visibility_continuous_px,
                    result.deflection_px,
                )
                r.folded, r.islands = result.folded, result.islands
                r.status, r.status_reason = result.status, result.status_reason
                self.displacement = result.displacement_px
                self._case_done = True
        if self._phase_job is not None and self._phase_job.done():
            key, result, error = self._phase_job.result()
            self._phase_job, taken = None, True
            if key[0] == self.traces and error is not None:
                self.readout.error = error
                self.readout.phase_for = key
            elif key[0] == self.traces:
                self.readout.at_phase_px, self.readout.at_phase_islands = (
                    result.distance_px,
                    result.islands,
                )
                self.readout.phase_for = key
        return taken

    def start_metrics(self) -> None:
        """Give the workers what is missing: the whole case once per trace, the
        comparison at the current phase whenever the phase changed, and in an instrument
        view the station's case whenever the scene changed. A job is never replaced
        before it was collected (throttled, never queued up)."""
        self._start_instrument()
        if self.v0 is None or self._baseline is None or self.readout.error is not None:
            return
        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=2, thread_name_prefix="glshade-metric")
        trace, baseline, v1, scene = self.traces, self._baseline, self.v1, self.scene
        if not self._case_done and self._case_job is None:

            def case() -> vis.Visibility:  # measured and judged as every front end does
                analysed, traced = baseline.get(), np.asarray(v1)
                return judged(scene, analysed, traced, analysed.measure(traced))

            self._case_job = self._pool.submit(_attempt, trace, case)
        key = (trace, self.scene.emitter.phase)
        if self._phase_job is None and self.readout.phase_for != key:
            phase = self.scene.emitter.phase
            self._phase_job = self._pool.submit(
                _attempt, key, lambda: baseline.get().at_phase(v1, phase)
            )

    def _start_instrument(self) -> None:
        """In an instrument view, give the station the scene (a change of the stripes'
        phase is none)."""
        offered = self.instrument_view
        if offered is not None:
            self.cases.start(offered, geometry_key(self.scene), self._case_size(offered))

    def wait_for_metrics(self, timeout_s: float = 60.0) -> None:
        """Block until the jobs in flight are done and collected (tests, scripted runs)."""
        jobs = (self._case_job, self._phase_job, self.cases.job)
        _, pending = wait_for([job for job in jobs if job is not None], timeout=timeout_s)
        if pending:
            raise TimeoutError(f"the visibility metrics took more than {timeout_s:g} s")
        self.collect_metrics()

    def settle_metrics(self, timeout_s: float = 60.0) -> None:
        """Wait until the readout is that of the current scene and phase: the jobs in
        flight, then the current phase's comparison if they were for an earlier one (the
        end of a scripted run)."""
        self.wait_for_metrics(timeout_s)
        self.start_metrics()
        self.wait_for_metrics(timeout_s)

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        self.cases.close()


#: Frames drawn after the last input event: imgui answers an event a frame or two later
#: (it spreads a press and a release over two frames), then the panel shows the result.
SETTLE_FRAMES = 4
#: How long an idle window waits for an event before looking again (seconds); while the
#: worker measures, it looks for the result this often instead.
IDLE_WAIT_S = 0.5
POLL_S = 1 / 30


@dataclass
class FrameSchedule:
    """When the window draws, so that an untouched window does no work: on input and for
    :data:`SETTLE_FRAMES` frames after it, while the phase is animated, when the worker
    hands in a result or the scene awaits its trace, and every frame of a scripted run
    (``continuous``). Otherwise the window waits for events without drawing."""

    continuous: bool = False
    owed: int = SETTLE_FRAMES  # the first frames

    def poke(self, frames: int = SETTLE_FRAMES) -> None:
        """Something happened (input, a resize, an edit in the panel): draw a few frames."""
        self.owed = max(self.owed, frames)

    def wants_frame(self, model: ViewerModel) -> bool:
        """Whether the next loop turn draws (takes the worker's finished results)."""
        news = model.collect_metrics()
        return self.continuous or model.animate or news or model.needs_trace or self.owed > 0

    def drew(self) -> None:
        self.owed = max(0, self.owed - 1)

    def wait_s(self, model: ViewerModel) -> float:
        """How long to wait for an event when no frame is wanted."""
        return POLL_S if model.metrics_pending else IDLE_WAIT_S


@dataclass
class ViewerOptions:
    """What ``glshade view`` was asked for (``measure``: the scene file's ``[measure]``)."""

    scene: Scene
    view: str = "image"
    animate: bool = False
    frames: int | None = None
    screenshot: Path | None = None
    benchmark: str | None = None  # "phase" or "theta": time frames and print fps
    panel: bool = True
    out_dir: Path = Path(".")
    pmd_size: int | None = None  # --set pmd_size: an instrument view's case size
    measure: MeasureTable | None = None
