"""The viewer's window (moderngl-window, pyglet) and its GL resources: it traces with the
batch renderer into the window's own context, shades phase changes on the GPU
(``shaders/viewer_display.frag.glsl``), draws the panel and handles input. Importing this
module needs the ``viewer`` extra."""

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

from glshade.app.viewer.model import ViewerModel, ViewerOptions
from glshade.app.viewer.panel import PANEL_WIDTH, draw_panel
from glshade.errors import GlshadeError
from glshade.files import write_png
from glshade.gpu.compose import compose_display, display_features, display_uniforms
from glshade.gpu.context import GLContext
from glshade.gpu.renderer import Renderer
from glshade.rig import orbit


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
            self.options.scene, view=self.options.view, animate=self.options.animate
        )
        self.renderer = Renderer(GLContext.wrap(self.ctx))
        self._programs: dict = {}  # the display pass, per the emitter's features
        self._textures()
        self.gui = None
        if self.options.panel:
            imgui.create_context()
            imgui.get_io().set_ini_filename("")  # no imgui.ini in the working directory
            self.gui = ModernglWindowRenderer(self.wnd)
        self.status = {"hover": "", "message": "", "scale_top": 0.0}
        self.started = self.last = time.perf_counter()
        self.shown_for = None

    def _textures(self) -> None:
        cam = self.options.scene.camera
        w, h = cam.width, cam.height
        self.tex_uv = self.ctx.texture((w, h), 2, dtype="f4")  # the scene's uv map
        self.tex_uv0 = self.ctx.texture((w, h), 2, dtype="f4")  # its defect-free twin's
        self.tex_gray = self.ctx.texture((w, h), 1, dtype="f4")
        self.tex_rgba = self.ctx.texture((w, h), 4, dtype="f1")
        self.shown_uv = self.tex_uv
        for texture in (self.tex_uv, self.tex_uv0, self.tex_gray, self.tex_rgba):
            texture.filter = (moderngl.NEAREST, moderngl.NEAREST)

    # ------------------------------------------------------------ work
    def trace(self):
        m = self.model
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
        if m.view == "overlay":
            self.tex_rgba.write(m.overlay_rgba().tobytes())
            return 2
        if m.view == "displacement":
            rgba, self.status["scale_top"] = m.displacement_rgba()
            self.tex_rgba.write(rgba.tobytes())
            return 2
        scene = m.scene if m.view == "image" else m.scene.without_defect()
        if m.shades_from_uv:  # a phase change only re-shades the traced map
            self.shown_uv = self.tex_uv if m.view == "image" else self.tex_uv0
            m.reshades += 1
            return 0
        image = self.renderer.render(
            scene
        ).image  # Blinn-Phong, supersampling, or the defect-free view
        self.wnd.fbo.use()
        self.tex_gray.write(np.ascontiguousarray(image).tobytes())
        return 1

    def _state(self):
        m = self.model
        return (m.traced_for, m.scene.emitter.phase, m.view, m.displacement is not None)

    # ------------------------------------------------------------ frame
    def on_render(self, time_s, frame_time):
        now = time.perf_counter()
        m, stats = self.model, self.stats
        if self.options.benchmark == "theta":
            m.set("theta", 30.0 + 30.0 * (0.5 + 0.5 * math.sin(stats["frames"] * 0.05)))
        m.advance(now - self.last)
        self.last = now
        if m.needs_trace:
            self.trace()
        m.collect_metrics()
        m.start_metrics()
        if self._state() != self.shown_for:
            self.mode = self.picture()
            self.shown_for = self._state()
        self.draw()
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
        cam = self.options.scene.camera
        self.wnd.fbo.use()
        self.ctx.clear(0.12, 0.12, 0.12)
        self.ctx.viewport = (0, self.wnd.buffer_size[1] - cam.height, cam.width, cam.height)
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
                program[name].value = value
        quad.render(moderngl.TRIANGLES, vertices=3)
        self.ctx.viewport = (0, 0, *self.wnd.buffer_size)
        if self.gui is not None:
            draw_panel(self.model, cam.width, self.wnd.buffer_size[1], self.status)
            self.gui.render(imgui.get_draw_data())

    # ------------------------------------------------------------ input
    def on_key_event(self, key, action, modifiers):
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

    def _save(self, screenshot: bool, out_dir: Path) -> None:
        """S and T: a screenshot or the scene; a refusal (an unwritable directory, a
        special file in the way) is shown in the panel, the window stays open."""
        try:
            if screenshot:
                path = self.screenshot(out_dir / f"glshade_view_{self.stats['frames']}.png")
            else:
                path = out_dir / "glshade_view.toml"
                self.model.scene.save(path)
        except GlshadeError as exc:
            self.status["message"] = f"not saved: {exc}"
            return
        self.status["message"] = f"wrote {path}"

    def on_mouse_position_event(self, x, y, dx, dy):
        if self.gui is not None:
            self.gui.mouse_position_event(x, y, dx, dy)
        self.status["hover"] = self.model.hover(int(x), int(y))

    def on_mouse_drag_event(self, x, y, dx, dy):
        if self.gui is not None:
            self.gui.mouse_drag_event(x, y, dx, dy)
            if imgui.get_io().want_capture_mouse:
                return
        self.orbit(dx, dy)

    def orbit(self, dx: float, dy: float) -> None:
        """A drag over the image orbits the rig: up raises the camera, right turns the
        camera and the emitter about the surface normal (:func:`glshade.rig.orbit`)."""
        cam = self.model.scene.camera
        theta, azimuth = orbit(cam.theta_deg, cam.azimuth_deg, dx, dy)
        self.model.set_value("camera.theta_deg", theta)
        self.model.set_value("camera.azimuth_deg", azimuth)

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
        stats["traces"], stats["reshades"] = m.traces, m.reshades
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
        if self.options.screenshot is not None:
            self.screenshot(self.options.screenshot)
        m.close()
        self.wnd.close()

    def on_close(self):
        self.model.close()


def make_app(options: ViewerOptions) -> tuple[type[ViewerWindow], dict]:
    """The window class for ``options`` and the dict its run fills with statistics."""
    cam = options.scene.camera
    panel_width = PANEL_WIDTH if options.panel else 0
    stats: dict = {"frames": 0, "seconds": 0.0, "traces": 0, "reshades": 0}
    size = (cam.width + panel_width, max(cam.height, 560 if panel_width else 0))
    attributes = {
        "options": options,
        "stats": stats,
        "window_size": size,
        "log_level": logging.WARNING,
    }  # moderngl-window's INFO lines are not the user's business
    return type("ViewerApp", (ViewerWindow,), attributes), stats


def run(options: ViewerOptions) -> dict:
    """Open the window and run until it is closed (or ``frames`` frames were drawn)."""
    app, stats = make_app(options)
    mglw.run_window_config(app, args=["--window", "pyglet"])
    return stats
