"""Interactive viewer (``glshade view``): turn the knobs and watch the stripes bend.

A moderngl-window window (pyglet) with an imgui-bundle control panel. The scene is traced
by the same :class:`~glshade.gpu.renderer.Renderer` and shaders as the batch renderer, into the
window's own GL context. What is recomputed is only what changed:

- a change of geometry (surface, θ, defect, emitter distance or stripes, precision,
  reflection, supersampling) re-traces the uv maps of the scene and of its defect-free
  twin;
- a change of phase (or its animation) only re-shades them on the GPU
  (``shaders/viewer_display.frag.glsl`` uses the renderer's own ``stripes.glsl``); with
  Blinn-Phong or supersampling, where the picture is not a function of the uv map, the
  image is re-rendered instead;
- the visibility metrics run in a worker thread, never on the render thread, and the
  panel shows the latest finished result.

``ViewerModel`` holds everything but the window and is tested without a display; the
scripted mode (``--frames N --screenshot out.png --set theta=5``) runs a real window for
tests and demos. Needs the ``viewer`` extra: ``pip install "glshade[viewer]"``.
"""

from __future__ import annotations

import math
import threading
import time
from concurrent.futures import Future, ThreadPoolExecutor
from concurrent.futures import wait as wait_for
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from glshade.errors import GlshadeError, SceneError
from glshade.metrics import contours
from glshade.metrics import visibility as vis
from glshade.scene import Scene, paper_scene

VIEWS = ("image", "defect-free", "overlay", "displacement")
PANEL_WIDTH = 360


@dataclass(frozen=True)
class Control:
    """A slider: the scene-file key it edits and its range (values are clamped to it)."""

    name: str
    table: str
    key: str
    lo: float
    hi: float
    log: bool = False
    fmt: str = "%.3f"


CONTROLS = {
    c.name: c
    for c in (
        Control("theta", "camera", "theta_deg", 0.5, 89.5, fmt="%.1f deg"),
        Control("radius", "surface", "radius", 5.0, 2000.0, log=True, fmt="%.1f mm"),
        Control("sigma2", "defect", "sigma2", 0.05, 100.0, log=True, fmt="%.2f mm2"),
        Control("sigma_x2", "defect", "sigma_x2", 0.05, 100.0, log=True, fmt="%.2f mm2"),
        Control("sigma_z2", "defect", "sigma_z2", 0.05, 100.0, log=True, fmt="%.2f mm2"),
        Control("sigma_xz", "defect", "sigma_xz", -100.0, 100.0, fmt="%.3f mm2"),
        Control("dmax", "defect", "dmax", -0.05, 0.05, fmt="%.4f mm"),
        Control("x0", "defect", "x0", -15.0, 15.0, fmt="%.2f mm"),
        Control("z0", "defect", "z0", -15.0, 15.0, fmt="%.2f mm"),
        Control("period", "emitter", "period", 0.2, 20.0, log=True, fmt="%.2f mm"),
        Control("stripe_sigma", "emitter", "stripe_sigma", 0.02, 10.0, log=True, fmt="%.3f mm"),
        Control("phase", "emitter", "phase", -1000.0, 1000.0, fmt="%.3f mm"),
        Control("shininess", "render", "shininess", 100.0, 1e10, log=True, fmt="%.3g"),
        Control("supersample", "render", "supersample", 1, 8, fmt="%d"),
    )
}
CHOICES = {
    "surface": ("surface", "kind", ("flat", "cylinder", "sphere")),
    "axis": ("surface", "axis", ("z", "x")),
    "reflection": ("render", "reflection", ("mirror", "blinn-phong")),
    "precision": ("render", "precision", ("fp32", "fp64")),
}


def clamp(control: Control, value: float) -> float:
    value = min(max(float(value), control.lo), control.hi)
    return int(round(value)) if control.fmt == "%d" else value


def apply_setting(scene: Scene, name: str, value) -> Scene:
    """The scene with one viewer setting changed; numbers are clamped to the control's
    range and the result validated by the scene model (a SceneError leaves it unchanged
    for the caller to report)."""
    if name in CHOICES:
        table, key, allowed = CHOICES[name]
        if value not in allowed:
            raise SceneError(f"{table}.{key}", "one of " + ", ".join(allowed), value)
        return scene.updated(**{table: {key: value}})
    if name == "concave":
        radius = abs(scene.surface.radius)
        return scene.updated(surface={"radius": -radius if bool(value) else radius})
    control = CONTROLS.get(name)
    if control is None:
        raise GlshadeError(f"--set {name}: unknown setting; allowed: {', '.join([*CONTROLS, *CHOICES, 'concave'])}")
    value = clamp(control, value)
    if name == "radius":
        value = math.copysign(value, scene.surface.radius)
    if name == "sigma_xz":  # keep the covariance positive definite
        bound = 0.999 * math.sqrt(scene.defect.sigma_x2 * scene.defect.sigma_z2)
        value = min(max(value, -bound), bound)
    if name == "stripe_sigma":
        value = min(value, 0.5 * scene.emitter.period)
    return scene.updated(**{control.table: {control.key: value}})


def parse_sets(items: list[str], scene: Scene) -> tuple[Scene, dict[str, str]]:
    """``--set name=value`` items: scene settings are applied (clamped, validated); the
    viewer's own (``view``, ``animate``) are returned."""
    extra: dict[str, str] = {}
    for item in items:
        name, sep, raw = item.partition("=")
        name = name.strip()
        if not sep or not name:
            raise GlshadeError(f"--set {item!r}: expected name=value")
        if name == "view":
            if raw not in VIEWS:
                raise GlshadeError(f"--set view: must be one of {', '.join(VIEWS)}, got {raw!r}")
            extra[name] = raw
        elif name == "animate":
            extra[name] = raw
        elif name in CHOICES:
            scene = apply_setting(scene, name, raw)
        elif name == "concave":
            scene = apply_setting(scene, name, raw.lower() in ("1", "true", "yes"))
        else:
            try:
                number = float(raw)
            except ValueError:
                raise GlshadeError(f"--set {name}: expected a number, got {raw!r}") from None
            if not math.isfinite(number):
                raise GlshadeError(f"--set {name}: expected a finite number, got {raw!r}")
            scene = apply_setting(scene, name, number)
    return scene, extra


def geometry_key(scene: Scene) -> Scene:
    """What a trace depends on: everything but the phase."""
    return scene.with_phase(0.0)


@dataclass
class Readout:
    """The panel's numbers, the latest the worker finished: the paper's comparison at the
    current phase, and the whole case (SPEC §6) measured by the same pipeline as
    ``glshade paper`` and ``glshade measure``."""

    at_phase_px: float | None = None       # the paper's metric at the phase shown
    at_phase_islands: int | None = None
    visibility_px: float | None = None     # the paper's metric over the phase sweep
    best_phase_mm: float | None = None
    continuous_px: float | None = None     # its continuous limit
    deflection_px: float | None = None
    folded: bool | None = None
    islands: int | None = None
    phase_for: tuple | None = None
    error: str | None = None               # why this geometry cannot be measured


def readout_lines(r: Readout) -> list[str]:
    """The panel's readout as text ("..." while the worker is still measuring, "-" and
    the reason when the metric refuses the scene)."""

    def px(value, fmt):
        if value is None:
            return "-" if r.error is not None else "..."
        return f"{value:{fmt}} px"

    best = "" if r.best_phase_mm is None else f" (phase {r.best_phase_mm:g} mm)"
    lines = [
        f"visibility, this phase: {px(r.at_phase_px, 'g')}",
        f"visibility, best phase: {px(r.visibility_px, 'g')}{best}",
        f"continuous limit: {px(r.continuous_px, '.2f')}",
        f"deflection: {px(r.deflection_px, '.2f')}",
    ]
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
    metrics, and which work a change calls for."""

    scene: Scene
    view: str = "image"
    animate: bool = False
    phase_speed_periods: float = 0.5  # periods per second when animating
    settings: vis.MetricSettings = field(default_factory=vis.MetricSettings)  # as glshade paper
    v0: np.ndarray | None = None      # traced emitter maps (v only), defect-free and defect
    v1: np.ndarray | None = None
    uv1: np.ndarray | None = None
    displacement: np.ndarray | None = None
    readout: Readout = field(default_factory=Readout)
    traced_for: Scene | None = None
    traces: int = 0
    reshades: int = 0
    _baseline: _Once | None = None
    _pool: ThreadPoolExecutor | None = None
    _case_job: Future | None = None
    _phase_job: Future | None = None
    _case_done: bool = False

    # ---------------------------------------------------------------- edits
    def set(self, name: str, value) -> bool:
        """Apply one control; False (and no change) when the value is rejected."""
        try:
            self.scene = apply_setting(self.scene, name, value)
        except (SceneError, GlshadeError):
            return False
        return True

    def reset(self) -> None:
        cam = self.scene.camera
        self.scene = paper_scene(self.scene.surface.kind).with_size(cam.width)
        self.view, self.animate = "image", False

    def advance(self, seconds: float) -> None:
        if self.animate:
            period = self.scene.emitter.period
            self.scene = self.scene.with_phase((self.scene.emitter.phase + self.phase_speed_periods * period * seconds) % period)

    @property
    def needs_trace(self) -> bool:
        return self.traced_for != geometry_key(self.scene)

    @property
    def shades_from_uv(self) -> bool:
        """The picture is a function of the uv map (mirror, one ray per pixel)."""
        from glshade.metrics.measurement import shades_from_map

        return shades_from_map(self.scene)

    def traced(self, uv_defect: np.ndarray, v_normal: np.ndarray) -> None:
        self.uv1 = uv_defect
        self.v1 = np.ascontiguousarray(uv_defect[..., 1])
        self.v0 = v_normal
        self.traced_for = geometry_key(self.scene)
        self.traces += 1
        self.displacement = None
        self.readout = Readout()
        v0, emitter, settings = self.v0, self.scene.emitter, self.settings
        self._baseline = _Once(lambda: vis.Baseline(v0, emitter, settings))
        self._case_done = False

    def baseline(self) -> vis.Baseline | None:
        """The defect-free analysis of the traced geometry (made once, in whichever
        thread asks first)."""
        return self._baseline.get() if self._baseline is not None else None

    # ---------------------------------------------------------------- pictures
    def overlay_rgba(self) -> np.ndarray:
        """Fig. 9 colours on the kept columns, as the metric sees them (normal blue, defect
        red, both magenta, islands orange); the columns cut off are dark grey."""
        h, w = self.v1.shape
        rgba = np.zeros((h, w, 4), np.uint8)
        rgba[..., :3] = 40
        rgba[..., 3] = 255
        try:
            baseline = self.baseline()
        except GlshadeError:  # the metric refuses this scene (the readout says why)
            baseline = None
        if baseline is not None and baseline.half_width_mm is not None:
            normal, defect = baseline.stripes_at(self.v1, self.scene.emitter.phase)
            rgba[:, baseline.columns, :3] = contours.overlay_rgb(normal, defect)
        return rgba

    def displacement_rgba(self) -> tuple[np.ndarray, float]:
        """The displacement (deflection) as a colour map with a scale bar (bottom right),
        and the value at its top end (px)."""
        from matplotlib import colormaps

        h, w = self.v1.shape
        rgba = np.zeros((h, w, 4), np.uint8)
        rgba[..., 3] = 255
        if self.displacement is None:
            return rgba, 0.0
        top = float(np.nanmax(self.displacement)) if np.isfinite(self.displacement).any() else 0.0
        scale = top if top > 0 else 1.0
        lut = (colormaps["viridis"](np.linspace(0, 1, 256))[:, :3] * 255).astype(np.uint8)
        values = np.nan_to_num(self.displacement / scale, nan=-1.0)
        index = np.clip((values * 255).astype(int), 0, 255)
        rgba[..., :3] = np.where(values[..., None] >= 0, lut[index], 0)
        bar_h, bar_w = max(4, h // 40), max(16, w // 4)
        ramp = np.linspace(0, 255, bar_w).astype(int)
        rgba[h - 2 * bar_h : h - bar_h, w - bar_w - bar_h : w - bar_h, :3] = lut[ramp][None]
        return rgba, top

    def hover(self, col: int, row: int) -> str:
        if self.uv1 is None or not (0 <= row < self.uv1.shape[0] and 0 <= col < self.uv1.shape[1]):
            return ""
        u, v = self.uv1[row, col]
        if not np.isfinite(v):
            return f"pixel ({col}, {row}): no emitter hit"
        text = f"pixel ({col}, {row}): u {u:.3f} mm, v {v:.3f} mm"
        if self.displacement is not None and np.isfinite(self.displacement[row, col]):
            text += f", displacement {self.displacement[row, col]:.2f} px"
        return text

    # ---------------------------------------------------------------- metrics
    def collect_metrics(self) -> None:
        """Take whatever the worker finished (call before :meth:`start_metrics`)."""
        if self._case_job is not None and self._case_job.done():
            trace, result, error = self._case_job.result()
            self._case_job = None
            if trace == self.traces and error is not None:
                self.readout.error = error
                self._case_done = True
            elif trace == self.traces:
                r = self.readout
                r.visibility_px, r.best_phase_mm = result.visibility_px, result.best_phase_mm
                r.continuous_px, r.deflection_px = result.visibility_continuous_px, result.deflection_px
                r.folded, r.islands = result.folded, result.islands
                self.displacement = result.displacement_px
                self._case_done = True
        if self._phase_job is not None and self._phase_job.done():
            key, result, error = self._phase_job.result()
            self._phase_job = None
            if key[0] == self.traces and error is not None:
                self.readout.error = error
                self.readout.phase_for = key
            elif key[0] == self.traces:
                self.readout.at_phase_px, self.readout.at_phase_islands = result.distance_px, result.islands
                self.readout.phase_for = key

    def start_metrics(self) -> None:
        """Give the worker what is missing: the whole case once per trace, and the
        comparison at the current phase whenever the phase changed. A job is never
        replaced before it was collected (throttled, never queued up)."""
        if self.v0 is None or self._baseline is None or self.readout.error is not None:
            return
        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=2, thread_name_prefix="glshade-metric")
        trace, baseline, v1 = self.traces, self._baseline, self.v1
        if not self._case_done and self._case_job is None:
            self._case_job = self._pool.submit(_attempt, trace, lambda: baseline.get().measure(v1))
        key = (trace, self.scene.emitter.phase)
        if self._phase_job is None and self.readout.phase_for != key:
            phase = self.scene.emitter.phase
            self._phase_job = self._pool.submit(_attempt, key, lambda: baseline.get().at_phase(v1, phase))

    def wait_for_metrics(self, timeout_s: float = 60.0) -> None:
        """Block until the jobs in flight are done and collected (tests, scripted runs)."""
        jobs = [job for job in (self._case_job, self._phase_job) if job is not None]
        _, pending = wait_for(jobs, timeout=timeout_s)
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


@dataclass
class ViewerOptions:
    """What ``glshade view`` was asked for."""

    scene: Scene
    view: str = "image"
    animate: bool = False
    frames: int | None = None
    screenshot: Path | None = None
    benchmark: str | None = None  # "phase" or "theta": time frames and print fps
    panel: bool = True
    out_dir: Path = Path(".")


def run(options: ViewerOptions) -> dict:
    """Open the window and run until it is closed (or ``frames`` frames were drawn).
    Returns the run's statistics (frames, seconds, traces)."""
    try:
        import moderngl_window as mglw
        from imgui_bundle import imgui  # noqa: F401
    except ImportError as exc:
        raise GlshadeError(f"the viewer needs the viewer extra ({exc.name} is missing): pip install \"glshade[viewer]\"") from None
    app, stats = make_app(options)
    mglw.run_window_config(app, args=["--window", "pyglet"])
    return stats


def make_app(options: ViewerOptions):
    """The moderngl-window ``WindowConfig`` for ``options`` (imports the viewer extra)."""
    import moderngl
    import moderngl_window as mglw
    from imgui_bundle import imgui
    from moderngl_window.integrations.imgui_bundle import ModernglWindowRenderer

    from glshade.files import write_png
    from glshade.gpu.compose import render_template
    from glshade.gpu.context import GLContext
    from glshade.gpu.renderer import Renderer

    cam = options.scene.camera
    panel_width = PANEL_WIDTH if options.panel else 0
    stats: dict = {"frames": 0, "seconds": 0.0, "traces": 0, "reshades": 0}

    class ViewerApp(mglw.WindowConfig):
        gl_version = (4, 5)
        title = "glshade view"
        window_size = (cam.width + panel_width, max(cam.height, 560 if panel_width else 0))
        aspect_ratio = None
        resizable = False
        vsync = False

        def __init__(self, **kwargs):
            super().__init__(**kwargs)
            self.model = ViewerModel(options.scene, view=options.view, animate=options.animate)
            self.renderer = Renderer(GLContext.wrap(self.ctx))
            self.program = self.ctx.program(
                vertex_shader=render_template("viewer_display.vert.glsl"),
                fragment_shader=render_template("viewer_display.frag.glsl"),
            )
            self.quad = self.ctx.vertex_array(self.program, [])
            w, h = cam.width, cam.height
            self.tex_uv = self.ctx.texture((w, h), 2, dtype="f4")       # the scene's uv map
            self.tex_uv0 = self.ctx.texture((w, h), 2, dtype="f4")      # its defect-free twin's
            self.tex_gray = self.ctx.texture((w, h), 1, dtype="f4")
            self.tex_rgba = self.ctx.texture((w, h), 4, dtype="f1")
            self.shown_uv = self.tex_uv
            for texture in (self.tex_uv, self.tex_uv0, self.tex_gray, self.tex_rgba):
                texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self.gui = None
            if options.panel:
                imgui.create_context()
                imgui.get_io().set_ini_filename("")  # no imgui.ini in the working directory
                self.gui = ModernglWindowRenderer(self.wnd)
            self.hover_text = ""
            self.message = ""
            self.started = time.perf_counter()
            self.last = self.started
            self.scale_top = 0.0
            self.shown_for = None

        # ------------------------------------------------------------ work
        def trace(self):
            m = self.model
            frame = self.renderer.render(m.scene, ("uv",))
            normal = self.renderer.render(m.scene.without_defect(), ("uv",))
            uv = frame.uv.astype(np.float32)
            m.traced(uv, np.ascontiguousarray(normal.uv[..., 1], dtype=np.float32))
            self.tex_uv.write(np.ascontiguousarray(uv).tobytes())
            self.tex_uv0.write(np.ascontiguousarray(normal.uv, dtype=np.float32).tobytes())
            self.wnd.fbo.use()

        def picture(self):
            """Fill the texture the current view draws from; returns the display mode."""
            m = self.model
            if m.view == "overlay":
                self.tex_rgba.write(m.overlay_rgba().tobytes())
                return 2
            if m.view == "displacement":
                rgba, self.scale_top = m.displacement_rgba()
                self.tex_rgba.write(rgba.tobytes())
                return 2
            scene = m.scene if m.view == "image" else m.scene.without_defect()
            if m.shades_from_uv:  # a phase change only re-shades the traced map
                self.shown_uv = self.tex_uv if m.view == "image" else self.tex_uv0
                m.reshades += 1
                return 0
            image = self.renderer.render(scene).image  # Blinn-Phong, supersampling, or the defect-free view
            self.wnd.fbo.use()
            self.tex_gray.write(np.ascontiguousarray(image).tobytes())
            return 1

        # ------------------------------------------------------------ frame
        def on_render(self, time_s, frame_time):
            now = time.perf_counter()
            m = self.model
            if options.benchmark == "theta":
                m.set("theta", 30.0 + 30.0 * (0.5 + 0.5 * math.sin(stats["frames"] * 0.05)))
            m.advance(now - self.last)
            self.last = now
            if m.needs_trace:
                self.trace()
            m.collect_metrics()
            m.start_metrics()
            state = (m.traced_for, m.scene.emitter.phase, m.view, m.displacement is not None)
            if state != self.shown_for:
                self.mode = self.picture()
                self.shown_for = state
            self.draw()
            stats["frames"] += 1
            if options.frames is not None and stats["frames"] >= options.frames:
                self.finish()

        def draw(self):
            m = self.model
            self.wnd.fbo.use()
            self.ctx.clear(0.12, 0.12, 0.12)
            w, h = cam.width, cam.height
            win_h = self.wnd.buffer_size[1]
            self.ctx.viewport = (0, win_h - h, w, h)
            emitter = m.scene.emitter
            for name, value in (("u_mode", self.mode), ("u_period", emitter.period),
                                ("u_stripe_sigma", emitter.sigma_mm), ("u_phase", emitter.phase)):
                if name in self.program:
                    self.program[name].value = value
            self.shown_uv.use(0)
            self.tex_gray.use(1)
            self.tex_rgba.use(2)
            for name, unit in (("u_uv", 0), ("u_gray", 1), ("u_rgba", 2)):
                if name in self.program:
                    self.program[name].value = unit
            self.quad.render(moderngl.TRIANGLES, vertices=3)
            self.ctx.viewport = (0, 0, *self.wnd.buffer_size)
            if self.gui is not None:
                self.panel()

        def panel(self):
            m = self.model
            imgui.new_frame()
            imgui.set_next_window_pos(imgui.ImVec2(cam.width, 0))
            imgui.set_next_window_size(imgui.ImVec2(PANEL_WIDTH, self.wnd.buffer_size[1]))
            imgui.begin("glshade", flags=imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_resize | imgui.WindowFlags_.no_collapse)
            s = m.scene
            self.combo("surface", s.surface.kind)
            if s.surface.kind != "flat":
                self.slider("radius", abs(s.surface.radius))
                changed, concave = imgui.checkbox("concave", s.surface.radius < 0)
                if changed:
                    m.set("concave", concave)
                if s.surface.kind == "cylinder":
                    self.combo("axis", s.surface.axis)
            self.slider("theta", s.camera.theta_deg)
            changed, full = imgui.checkbox("full covariance", not s.defect.isotropic)
            if changed and not full:
                m.set("sigma2", s.defect.sigma_x2)
            if changed and full:
                m.set("sigma_xz", 0.1 * math.sqrt(s.defect.sigma_x2 * s.defect.sigma_z2))
            if s.defect.isotropic and not full:
                self.slider("sigma2", s.defect.sigma_x2)
            else:
                for name in ("sigma_x2", "sigma_z2", "sigma_xz"):
                    self.slider(name, getattr(s.defect, name))
            for name in ("dmax", "x0", "z0"):
                self.slider(name, getattr(s.defect, name))
            self.slider("period", s.emitter.period)
            self.slider("stripe_sigma", s.emitter.sigma_mm)
            changed, value = imgui.slider_float("phase", float(s.emitter.phase), 0.0, float(s.emitter.period), "%.3f mm",
                                                imgui.SliderFlags_.always_clamp)
            if changed:
                m.set("phase", value)
            _, m.animate = imgui.checkbox("animate phase", m.animate)
            self.combo("reflection", s.render.reflection)
            if s.render.reflection == "blinn-phong":
                self.slider("shininess", s.render.shininess)
            self.combo("precision", s.render.precision)
            self.slider("supersample", s.render.supersample)
            changed, index = imgui.combo("view", VIEWS.index(m.view), list(VIEWS))
            if changed:
                m.view = VIEWS[index]
            imgui.separator()
            for line in readout_lines(m.readout):
                imgui.text(line)
            if m.readout.folded:
                imgui.text_colored(imgui.ImVec4(1.0, 0.6, 0.2, 1.0),
                                   f"the stripe map folds: {m.readout.islands} islands (not measured)")
            if m.view == "displacement":
                imgui.text(f"colour scale: 0 (dark) to {self.scale_top:.2f} px (yellow)")
            imgui.text_wrapped(self.hover_text or "hover over the image")
            imgui.text(f"{imgui.get_io().framerate:.0f} fps, {m.traces} traces")
            imgui.text_wrapped("keys: S screenshot, T save scene, R reset, O overlay")
            if self.message:
                imgui.text_wrapped(self.message)
            imgui.end()
            imgui.render()
            self.gui.render(imgui.get_draw_data())

        def slider(self, name, value):
            c = CONTROLS[name]
            flags = imgui.SliderFlags_.always_clamp | (imgui.SliderFlags_.logarithmic if c.log else 0)
            if c.fmt == "%d":
                changed, new = imgui.slider_int(name, int(value), int(c.lo), int(c.hi), "%d", flags)
            else:
                changed, new = imgui.slider_float(name, float(value), float(c.lo), float(c.hi), c.fmt, flags)
            if changed:
                self.model.set(name, new)

        def combo(self, name, value):
            allowed = CHOICES[name][2]
            changed, index = imgui.combo(name, allowed.index(value), list(allowed))
            if changed:
                self.model.set(name, allowed[index])

        # ------------------------------------------------------------ input
        def on_key_event(self, key, action, modifiers):
            if self.gui is not None:
                self.gui.key_event(key, action, modifiers)
            if action != self.wnd.keys.ACTION_PRESS or (self.gui is not None and imgui.get_io().want_capture_keyboard):
                return
            keys = self.wnd.keys
            if key == keys.S:
                shot = self.screenshot(options.out_dir / f"glshade_view_{stats['frames']}.png")
                self.message = f"wrote {shot}"
            elif key == keys.T:
                path = options.out_dir / "glshade_view.toml"
                self.model.scene.save(path)
                self.message = f"wrote {path}"
            elif key == keys.R:
                self.model.reset()
            elif key == keys.O:
                self.model.view = "image" if self.model.view == "overlay" else "overlay"

        def on_mouse_position_event(self, x, y, dx, dy):
            if self.gui is not None:
                self.gui.mouse_position_event(x, y, dx, dy)
            self.hover_text = self.model.hover(int(x), int(y))

        def on_mouse_drag_event(self, x, y, dx, dy):
            if self.gui is not None:
                self.gui.mouse_drag_event(x, y, dx, dy)

        def on_mouse_scroll_event(self, x_offset, y_offset):
            if self.gui is not None:
                self.gui.mouse_scroll_event(x_offset, y_offset)

        def on_mouse_press_event(self, x, y, button):
            if self.gui is not None:
                self.gui.mouse_press_event(x, y, button)

        def on_mouse_release_event(self, x, y, button):
            if self.gui is not None:
                self.gui.mouse_release_event(x, y, button)

        def on_unicode_char_entered(self, char):
            if self.gui is not None:
                self.gui.unicode_char_entered(char)

        # ------------------------------------------------------------ end
        def screenshot(self, path: Path) -> Path:
            width, height = self.wnd.buffer_size
            pixels = np.frombuffer(self.wnd.fbo.read(viewport=(0, 0, width, height), components=3), np.uint8)
            write_png(path, np.ascontiguousarray(pixels.reshape(height, width, 3)[::-1]))
            return Path(path)

        def finish(self):
            stats["seconds"] = time.perf_counter() - self.started
            stats["traces"] = self.model.traces
            stats["reshades"] = self.model.reshades
            # a scripted run ends on the numbers of its last frame, however fast it drew:
            # wait for the worker, and draw that frame again if the readout changed
            m = self.model
            before = replace(m.readout)
            m.settle_metrics()
            redraw = m.readout != before
            state = (m.traced_for, m.scene.emitter.phase, m.view, m.displacement is not None)
            if state != self.shown_for:  # the displacement view waits for the metrics
                self.mode = self.picture()
                self.shown_for = state
                redraw = True
            if redraw:
                self.draw()
            stats["readout"] = replace(m.readout)
            if options.screenshot is not None:
                self.screenshot(options.screenshot)
            self.model.close()
            self.wnd.close()

        def on_close(self):
            self.model.close()

    return ViewerApp, stats
