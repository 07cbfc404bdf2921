"""The viewer's window (moderngl-window, pyglet) and its GL resources: it traces with the
batch renderer into the window's own context, shades phase changes on the GPU
(``shaders/viewer_display.frag.glsl``), draws the panel and handles input. Importing this
module needs the ``viewer`` extra.

The window draws only when something changed (:class:`~glshade.app.viewer.model.FrameSchedule`):
its own loop waits for the window system's events instead of drawing flat out, and a
drawn frame re-runs the display pass only when the picture changed (the last one is kept
in a texture and copied). Untouched, the viewer sleeps."""

from __future__ import annotations

import logging
import math
import time
from dataclasses import replace
from pathlib import Path

import moderngl
import moderngl_window as mglw
import numpy as np
from imgui_bundle import imgui
from moderngl_window.integrations.imgui_bundle import ModernglWindowRenderer

from glshade.app.viewer.colourbar import BAR_HEIGHT, displacement_scale
from glshade.app.viewer.model import FrameSchedule, ViewerModel, ViewerOptions
from glshade.app.viewer.panel import PANEL_WIDTH, draw_panel, panel_height, panel_style
from glshade.errors import GlshadeError
from glshade.files import refuse_link, write_png
from glshade.gpu.compose import compose_display, display_features, display_uniforms
from glshade.gpu.context import GLContext, set_uniform
from glshade.gpu.renderer import Renderer
from glshade.rig import orbit, orbit_position

#: Copies the kept picture into the window, texel for texel (the same pixels as the
#: display pass drew, at the same place).
_COPY_VERTEX = """#version 330
void main() {
    vec2 corner = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);
    gl_Position = vec4(corner * 2.0 - 1.0, 0.0, 1.0);
}
"""
_COPY_FRAGMENT = """#version 330
uniform sampler2D u_picture;
uniform ivec2 u_origin;  // the viewport's lower-left corner in the window
out vec4 fragment;
void main() {
    fragment = texelFetch(u_picture, ivec2(gl_FragCoord.xy) - u_origin, 0);
}
"""


class ViewerWindow(mglw.WindowConfig):
    """The window; :func:`make_app` subclasses it with the run's ``options``/``stats``."""

    gl_version = (4, 5)
    title = "glshade view"
    aspect_ratio = None  # type: ignore[assignment]  # moderngl-window: None is the window's own
    resizable = False
    vsync = False
    options: ViewerOptions
    stats: dict

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.model = ViewerModel(
            self.options.scene,
            view=self.options.view,
            animate=self.options.animate,
            case_size=self.options.pmd_size,
            measure_table=self.options.measure,
        )
        self.renderer = Renderer(GLContext.wrap(self.ctx))
        self._programs: dict = {}  # the display pass, per the emitter's features
        self._textures()
        self.gui = None
        if self.options.panel:
            imgui.create_context()
            io = imgui.get_io()
            io.set_ini_filename("")  # no imgui.ini in the working directory
            io.config_input_text_cursor_blink = False  # a blinking caret would need frames
            panel_style()
            self.gui = ModernglWindowRenderer(self.wnd)
        self.status = {"hover": "", "message": "", "scale_top": 0.0, "frame_ms": 0.0}
        self.status["scale"] = None  # the colour bar's scale, in the colour-mapped views
        self.started = self.last = time.perf_counter()
        self.shown_for = None
        self.drawn_for: tuple | None = None  # what the last frame's picture showed
        self.kept_for: tuple | None = None  # what the kept texture shows
        self.schedule = FrameSchedule(continuous=self.options.frames is not None)
        self.stats.update(panel_bottom=0.0, panel_scroll=0.0, opened_at=tuple(self.wnd.size))
        window = getattr(self.wnd, "_window", None)  # pyglet's: redraw when uncovered
        if window is not None:
            window.push_handlers(on_expose=self.schedule.poke, on_show=self.schedule.poke)

    def _textures(self) -> None:
        cam = self.options.scene.camera
        w, h = cam.width, cam.height
        self.tex_uv = self.ctx.texture((w, h), 2, dtype="f4")  # the scene's uv map
        self.tex_uv0 = self.ctx.texture((w, h), 2, dtype="f4")  # its defect-free twin's
        self.tex_gray = self.ctx.texture((w, h), 1, dtype="f4")
        self.tex_rgba = self.ctx.texture((w, h), 4, dtype="f1")
        self.shown_uv = self.tex_uv
        self.tex_picture = self.ctx.texture((w, h), 4, dtype="f1")  # the display pass's
        for texture in (self.tex_uv, self.tex_uv0, self.tex_gray, self.tex_rgba, self.tex_picture):
            texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.picture_fbo = self.ctx.framebuffer(color_attachments=[self.tex_picture])
        copy = self.ctx.program(vertex_shader=_COPY_VERTEX, fragment_shader=_COPY_FRAGMENT)
        self._copy = (copy, self.ctx.vertex_array(copy, []))

    # ------------------------------------------------------------ work
    def renderer_state(self) -> None:
        """The GL state the batch renderer draws with (GL's defaults: no blending, no
        scissor). The panel leaves blending on (imgui's alpha blend), which turned the
        renderer's image black when a change of reflection or Fresnel model re-rendered
        it after the panel had been drawn."""
        self.ctx.enable_only(moderngl.NOTHING)
        self.ctx.scissor = None

    def trace(self):
        m = self.model
        self.renderer_state()
        frame = self.renderer.render(m.scene, ("uv",))
        normal = self.renderer.render(m.scene.without_defect(), ("uv",))
        uv = frame.output("uv").astype(np.float32)
        m.traced(uv, np.ascontiguousarray(normal.output("uv")[..., 1], dtype=np.float32))
        self.tex_uv.write(np.ascontiguousarray(uv).tobytes())
        self.tex_uv0.write(np.ascontiguousarray(normal.uv, dtype=np.float32).tobytes())
        self.wnd.fbo.use()

    def picture(self):
        """Fill the texture the current view draws from; returns the display mode."""
        m = self.model
        self.status["scale"] = None
        if m.view == "overlay":
            self.tex_rgba.write(m.overlay_rgba().tobytes())
            return 2
        if m.view == "displacement":
            rgba, top = m.displacement_rgba()
            self.status["scale_top"], self.status["scale"] = top, displacement_scale(top)
            self.tex_rgba.write(rgba.tobytes())
            return 2
        if m.instrument_view is not None:
            rgba, self.status["scale"] = m.instrument_rgba()
            self.tex_rgba.write(np.ascontiguousarray(rgba).tobytes())
            return 2
        scene = m.scene if m.view == "image" else m.scene.without_defect()
        if m.shades_from_uv:  # a phase change only re-shades the traced map
            self.shown_uv = self.tex_uv if m.view == "image" else self.tex_uv0
            m.reshades += 1
            return 0
        self.renderer_state()
        image = self.renderer.render(scene).image  # Blinn-Phong, supersampling, defect-free
        self.wnd.fbo.use()
        self.tex_gray.write(np.ascontiguousarray(image).tobytes())
        return 1

    def _state(self):
        m = self.model
        measured = m.view == "displacement" and m.displacement is not None
        cases = m.cases.taken if m.instrument_view is not None else None
        return (m.traced_for, m.scene.emitter.phase, m.view, measured, cases)

    # ------------------------------------------------------------ frame
    def on_render(self, time_s, frame_time):
        now = time.perf_counter()
        m, stats = self.model, self.stats
        if self.options.benchmark == "theta":
            m.set("theta", 30.0 + 30.0 * (0.5 + 0.5 * math.sin(stats["frames"] * 0.05)))
        m.advance(min(now - self.last, 0.1))  # after a rest the animation goes on, not jumps
        self.last = now
        if m.needs_trace:
            self.trace()
        m.collect_metrics()
        m.start_metrics()
        if self._state() != self.shown_for:
            self.mode = self.picture()
            self.shown_for = self._state()
        if self.gui is not None:
            imgui.get_io().delta_time = max(float(frame_time), 1e-4)
        self.draw()
        self.schedule.drew()
        if m.needs_trace or self._state() != self.shown_for:
            self.schedule.poke(1)  # the panel changed the scene: show it
        self.status["frame_ms"] = (time.perf_counter() - now) * 1e3
        stats["frames"] += 1
        if self.options.frames is not None and stats["frames"] >= self.options.frames:
            self.finish()

    def display(self):
        """The display pass's program and vertex array for the scene's emitter."""
        features = display_features(self.model.scene)
        if features not in self._programs:
            vertex, fragment = compose_display(features)
            program = self.ctx.program(vertex_shader=vertex, fragment_shader=fragment)
            self._programs[features] = (program, self.ctx.vertex_array(program, []), features)
        return self._programs[features]

    def draw(self):
        """One frame: the picture, then the panel. A picture that changed since the last
        frame is drawn by the display pass straight into the window (an animation pays
        one pass a frame); one that did not is copied from the kept texture, which the
        display pass fills once (a frame for the panel alone re-renders nothing)."""
        cam = self.options.scene.camera
        key = (self.model.scene, self.model.view, self.mode, self.shown_for, id(self.shown_uv))
        if key == self.drawn_for and key != self.kept_for:  # the picture settled: keep it
            self.picture_fbo.use()
            self.ctx.viewport = (0, 0, cam.width, cam.height)
            self.display_pass()
            self.kept_for = key
        origin = (0, self.wnd.buffer_size[1] - cam.height)
        self.wnd.fbo.use()
        self.ctx.clear(0.12, 0.12, 0.12)
        self.ctx.viewport = (*origin, cam.width, cam.height)
        if key == self.kept_for:
            program, quad = self._copy
            self.tex_picture.use(0)
            program["u_picture"] = 0
            program["u_origin"] = origin
            quad.render(moderngl.TRIANGLES, vertices=3)
        else:
            self.display_pass()
        self.drawn_for = key
        self.ctx.viewport = (0, 0, *self.wnd.buffer_size)
        if self.gui is not None:
            height = self.wnd.size[1]
            bottom, scroll = draw_panel(
                self.model, cam.width, height, self.status, (cam.width, cam.height)
            )
            self.gui.render(imgui.get_draw_data())
            self.stats["panel_bottom"] = max(self.stats["panel_bottom"], bottom)
            self.stats["panel_scroll"] = max(self.stats["panel_scroll"], scroll)
            self.fit(bottom)

    def display_pass(self):
        """The current view into the bound framebuffer's viewport."""
        self.model.scene_passes += 1
        program, quad, features = self.display()
        values = {
            **display_uniforms(self.model.scene, features),
            "u_mode": self.mode,
            "u_uv": 0,
            "u_gray": 1,
            "u_rgba": 2,
        }
        self.shown_uv.use(0)
        self.tex_gray.use(1)
        self.tex_rgba.use(2)
        for name, value in values.items():
            if name in program:
                set_uniform(program, name, value)
        quad.render(moderngl.TRIANGLES, vertices=3)

    def fit(self, bottom: float) -> None:
        """Grow the window when the panel outgrew it (another component's parameters, a
        long refusal), as far as the screen allows; it never shrinks under the user."""
        width, height = self.wnd.size
        needed = math.ceil(bottom)
        if needed <= height:
            return
        window = getattr(self.wnd, "_window", None)
        screen = getattr(getattr(window, "screen", None), "height", None)
        needed = min(needed, screen) if screen else needed
        if needed > height:
            self.wnd.size = (width, needed)
            self.schedule.poke()

    def on_resize(self, width, height):
        if self.gui is not None:
            self.gui.resize(width, height)
        self.drawn_for = self.kept_for = None
        self.schedule.poke()

    # ------------------------------------------------------------ input
    def on_key_event(self, key, action, modifiers):
        self.schedule.poke()  # every input may change the panel or the scene
        if self.gui is not None:
            self.gui.key_event(key, action, modifiers)
        if action != self.wnd.keys.ACTION_PRESS or (
            self.gui is not None and imgui.get_io().want_capture_keyboard
        ):
            return
        keys, out_dir = self.wnd.keys, self.options.out_dir
        if key in (keys.S, keys.T):
            self._save(key == keys.S, out_dir)
        elif key == keys.R:
            self.model.reset()
        elif key == keys.O:
            self.model.view = "image" if self.model.view == "overlay" else "overlay"
        elif key == keys.P:
            self.model.toggle_instrument_view()

    def _save(self, screenshot: bool, out_dir: Path) -> None:
        """S and T: a screenshot or the scene; a refusal (an unwritable directory, a
        special file in the way) is shown in the panel, the window stays open."""
        name = f"glshade_view_{self.stats['frames']}.png" if screenshot else "glshade_view.toml"
        path = out_dir / name
        try:
            refuse_link(out_dir, path, "S" if screenshot else "T")  # a name glshade chose
            if screenshot:
                self.screenshot(path, redraw=True)
            else:  # never over the scene file the viewer opened (the run's input)
                self.model.scene.save(path)
        except GlshadeError as exc:
            self.status["message"] = f"not saved: {exc}"
            return
        self.status["message"] = f"wrote {path}"

    def on_mouse_position_event(self, x, y, dx, dy):
        self.schedule.poke()
        if self.gui is not None:
            self.gui.mouse_position_event(x, y, dx, dy)
        # moderngl-window flips pyglet's y as height - y: the top row comes as 1, not 0
        self.status["hover"] = self.model.hover(int(x), int(y) - 1)

    def on_mouse_drag_event(self, x, y, dx, dy):
        self.schedule.poke()
        if self.gui is not None:
            self.gui.mouse_drag_event(x, y, dx, dy)
            if imgui.get_io().want_capture_mouse:
                return
        self.orbit(dx, dy)

    def orbit(self, dx: float, dy: float) -> None:
        """A drag over the image orbits the rig: up raises the camera, right turns the
        camera and the emitter about the surface normal (:func:`glshade.rig.orbit`). A
        look-at camera orbits the point it aims at (:func:`glshade.rig.orbit_position`);
        a camera placed by OpenCV's extrinsics turns its view (yaw and pitch)."""
        cam = self.model.scene.camera
        if cam.pose == "look_at":
            pose = cam.world_pose()
            moved = orbit_position(pose.position, pose.target, dx, dy)
            self.model.set_value("camera.position", tuple(float(x) for x in moved))
        elif cam.pose == "extrinsics":
            yaw = max(-180.0, min(180.0, cam.yaw_deg - 0.25 * dx))
            pitch = max(-180.0, min(180.0, cam.pitch_deg - 0.25 * dy))
            self.model.set_value("camera.yaw_deg", yaw)
            self.model.set_value("camera.pitch_deg", pitch)
        else:
            theta, azimuth = orbit(cam.theta_deg, cam.azimuth_deg, dx, dy)
            self.model.set_value("camera.theta_deg", theta)
            self.model.set_value("camera.azimuth_deg", azimuth)

    def on_mouse_scroll_event(self, x_offset, y_offset):
        self.schedule.poke()
        if self.gui is not None:
            self.gui.mouse_scroll_event(x_offset, y_offset)

    def on_mouse_press_event(self, x, y, button):
        self.schedule.poke()
        if self.gui is not None:
            self.gui.mouse_press_event(x, y, button)

    def on_mouse_release_event(self, x, y, button):
        self.schedule.poke()
        if self.gui is not None:
            self.gui.mouse_release_event(x, y, button)

    def on_unicode_char_entered(self, char):
        self.schedule.poke()
        if self.gui is not None:
            self.gui.unicode_char_entered(char)

    # ------------------------------------------------------------ end
    def screenshot(self, path: Path, redraw: bool = False) -> Path:
        """The window's pixels as a PNG; ``redraw``: draw the frame first (a key press
        comes between frames, when the back buffer holds nothing reliable)."""
        if redraw:
            self.draw()
        width, height = self.wnd.buffer_size
        pixels = np.frombuffer(
            self.wnd.fbo.read(viewport=(0, 0, width, height), components=3), np.uint8
        )
        write_png(path, np.ascontiguousarray(pixels.reshape(height, width, 3)[::-1]))
        return Path(path)

    def finish(self):
        """End a scripted run on the numbers of its last frame, however fast it drew:
        wait for the worker, and draw that frame again if the readout changed."""
        m, stats = self.model, self.stats
        stats["seconds"] = time.perf_counter() - self.started
        before = replace(m.readout)
        m.settle_metrics()
        redraw = m.readout != before
        if self._state() != self.shown_for:  # the displacement view waits for the metrics
            self.mode = self.picture()
            self.shown_for = self._state()
            redraw = True
        if redraw:
            self.draw()
        stats["readout"] = replace(m.readout)
        stats["readout_lines"] = m.readout_text()
        stats["traces"], stats["reshades"] = m.traces, m.reshades
        stats["scene_passes"], stats["window_size"] = m.scene_passes, tuple(self.wnd.size)
        stats["scale_top"] = self.status["scale_top"]
        if self.options.screenshot is not None:
            self.screenshot(self.options.screenshot)
        m.close()
        self.wnd.close()

    def on_close(self):
        self.model.close()


def make_app(options: ViewerOptions) -> tuple[type[ViewerWindow], dict]:
    """The window class for ``options`` and the dict its run fills with statistics. With
    the panel, the window opens tall enough for all of it, and for the image with the
    colour bar beneath it where the screen has room for that."""
    cam = options.scene.camera
    stats: dict = {"frames": 0, "seconds": 0.0, "traces": 0, "reshades": 0}
    if options.panel:
        sample = ViewerModel(options.scene, view=options.view, animate=options.animate)
        below = cam.height + BAR_HEIGHT  # the displacement view's colour bar beneath
        screen = _screen_height()
        if screen is not None and below > 0.9 * screen:
            below = cam.height  # no room: the bar goes over the image's bottom edge
        height = max(below, panel_height(sample, (cam.width, cam.height)))
        size = (cam.width + PANEL_WIDTH, height)
    else:
        size = (cam.width, cam.height)
    attributes = {
        "options": options,
        "stats": stats,
        "window_size": size,
        "log_level": logging.WARNING,
    }  # moderngl-window's INFO lines are not the user's business
    return type("ViewerApp", (ViewerWindow,), attributes), stats


def _screen_height() -> int | None:
    """The default screen's height in pixels (None where pyglet cannot tell)."""
    try:
        import pyglet

        return int(pyglet.display.get_display().get_default_screen().height)
    except Exception:  # noqa: BLE001 - a guess is not worth failing over
        return None


def run(options: ViewerOptions) -> dict:
    """Open the window and run until it is closed (or ``frames`` frames were drawn)."""
    app, stats = make_app(options)
    config = mglw.create_window_config_instance(app, args=["--window", "pyglet"])
    assert isinstance(config, ViewerWindow)
    loop(config)
    return stats


def loop(config: ViewerWindow) -> None:
    """moderngl-window's main loop, drawing only the frames the schedule asks for: in
    between it waits for the window system's next event (or the worker's result), so an
    untouched window sleeps instead of drawing the same frame again and again."""
    window, timer = config.wnd, config.timer
    timer.start()
    while not window.is_closing:
        if config.schedule.wants_frame(config.model):
            current, delta = timer.next_frame()
            window.use()
            window.render(current, delta)
            if not window.is_closing:
                window.swap_buffers()  # also takes the events that came meanwhile
        else:
            wait_for_events(window, config.schedule.wait_s(config.model))
    timer.stop()
    window.destroy()


def wait_for_events(window, timeout_s: float) -> None:
    """Block until the window system has an event for us, or ``timeout_s`` passed, then
    hand the events to the window (pyglet's platform loop; a plain sleep without it)."""
    native = getattr(window, "_window", None)  # moderngl-window keeps pyglet's window here
    try:
        import pyglet

        pyglet.app.platform_event_loop.step(timeout_s)
    except Exception:  # noqa: BLE001 - no platform loop to wait on: poll instead
        time.sleep(min(timeout_s, 1 / 60))
    if native is not None:
        native.dispatch_events()
