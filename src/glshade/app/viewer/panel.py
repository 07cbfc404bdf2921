"""The viewer's control panel (imgui): the controls of the components in use, generated
from the parameter schema (:func:`glshade.app.viewer.controls.panel_params`), then the
view, the readout and the help line; and, in the displacement view, the colour bar.

The window opens tall enough for the whole panel (:func:`panel_height` lays it out once
before the window exists), so no item sits below the fold."""

from __future__ import annotations

import math
from dataclasses import replace

from imgui_bundle import imgui

from glshade.app.viewer.colourbar import colour_bar_layout, draw_colour_bar
from glshade.app.viewer.controls import combo, panel_params, slider
from glshade.app.viewer.model import ViewerModel
from glshade.params import Param

PANEL_WIDTH = 360
#: The status the panel is laid out with before the window opens: a hover line and a
#: save message as long as real ones, so that they fit too when they come.
SAMPLE_STATUS = {
    "hover": "pixel (1023, 1023): u -100.000 mm, v -100.000 mm, displacement 10.00 px",
    "message": "wrote glshade_view_10000.png",
    "scale_top": 0.0,
    "frame_ms": 0.0,
    "scale": None,
}
#: The panel lists the tables in this order (the surface first: it changes the most).
PANEL_TABLES = ("surface", "camera", "defect", "emitter", "render", "sensor")
#: Parameters drawn by a dedicated widget rather than a plain slider.
_SHORTHAND = "defect.sigma2"
_COVARIANCE = ("defect.sigma_x2", "defect.sigma_z2", "defect.sigma_xz")


def panel_style() -> None:
    """A little tighter than imgui's default (rows of 20 px instead of 23)."""
    style = imgui.get_style()
    style.frame_padding = imgui.ImVec2(4, 2)
    style.item_spacing = imgui.ImVec2(8, 3)
    style.window_padding = imgui.ImVec2(8, 6)


def panel_height(model: ViewerModel, image: tuple[int, int]) -> int:
    """The window height the panel needs for ``model``'s scene, in its view and in each
    instrument's first view (whose readout may be longer), laid out by imgui without a
    window (its own context, destroyed after)."""
    previous = imgui.get_current_context()
    context = imgui.create_context()
    try:
        io = imgui.get_io()
        io.set_ini_filename("")
        io.display_size = imgui.ImVec2(image[0] + PANEL_WIDTH, 4096)
        io.fonts.build()
        panel_style()
        bottoms = []
        for view in (model.view, *(o.view.name for o in model.first_views())):
            shown = replace(model, view=view)
            bottoms.append(draw_panel(shown, image[0], 4096, dict(SAMPLE_STATUS), image)[0])
    finally:
        imgui.destroy_context(context)
        if previous is not None:
            imgui.set_current_context(previous)
    return math.ceil(max(bottoms))


def draw_panel(
    model: ViewerModel, left: int, height: int, status: dict, image: tuple[int, int]
) -> tuple[float, float]:
    """One frame of the panel at ``x = left`` in a window ``height`` pixels high, and the
    colour bar over the ``image`` (width, height) in the displacement view; ``status``:
    hover text, message, scale top, frame time. Returns the y (window pixels) where the
    panel's content ends (its last item's bottom and the window's padding), and how far
    the panel could scroll (0 when all of it is in view)."""
    imgui.new_frame()
    imgui.set_next_window_pos(imgui.ImVec2(left, 0))
    imgui.set_next_window_size(imgui.ImVec2(PANEL_WIDTH, height))
    flags = (
        imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_resize | imgui.WindowFlags_.no_collapse
    )
    imgui.begin("glshade", flags=flags)
    params = panel_params(model.scene)
    for table in PANEL_TABLES:
        for param in (p for p in params if p.table == table):
            _parameter(model, param)
    _view_and_readout(model, status)
    bottom = imgui.get_item_rect_max().y + imgui.get_style().window_padding.y
    scroll = imgui.get_scroll_max_y()
    imgui.end()
    if status["scale"] is not None:
        draw_colour_bar(colour_bar_layout(*image, height), image[0], status["scale"])
    imgui.render()
    return bottom, scroll


def _parameter(model: ViewerModel, param: Param) -> None:
    scene = model.scene
    if param.path in _COVARIANCE:
        return  # drawn with the isotropic shorthand
    if param.path == _SHORTHAND:
        _covariance(model)
    elif param.value_type in ("text", "path"):
        _text_field(model, param)
    elif param.value_type == "choice":
        _combo(model, param.flag.lstrip("-") if param.flag else param.key, scene.value(param.path))
    elif param.path == "emitter.phase":
        pattern = scene.active.emitter.pattern(scene)
        changed, value = imgui.slider_float(
            "phase",
            float(pattern.phase_mm),
            0.0,
            float(pattern.period_mm),
            "%.3f mm",
            imgui.SliderFlags_.always_clamp,
        )
        if changed:
            model.set("phase", value)
        _, model.animate = imgui.checkbox("animate phase", model.animate)
    elif param.control is not None and param.control.signed:
        _slider(model, param.control.name, abs(scene.value(param.path)))
        changed, negative = imgui.checkbox("concave", scene.value(param.path) < 0)
        if changed:
            model.set("concave", negative)
    elif param.control is not None:
        _slider(model, param.control.name, getattr(scene, param.table).effective(param.key))


def _text_field(model: ViewerModel, param: Param) -> None:
    """A formula or a file path: edited in place, applied on Enter (refusals are shown)."""
    value = model.scene.value(param.path) or ""
    changed, text = imgui.input_text(
        param.key, str(value), imgui.InputTextFlags_.enter_returns_true
    )
    if changed and text != value:
        model.set_value(param.path, text)


def _covariance(model: ViewerModel) -> None:
    """An isotropic variance, or the three entries of a full covariance."""
    d = model.scene.defect
    changed, full = imgui.checkbox("full covariance", not d.isotropic)
    if changed and not full:
        model.set("sigma2", d.sigma_x2)
    if changed and full:
        model.set("sigma_xz", 0.1 * math.sqrt(d.sigma_x2 * d.sigma_z2))
    if d.isotropic and not full:
        _slider(model, "sigma2", d.sigma_x2)
    else:
        for path in _COVARIANCE:
            _slider(model, path.partition(".")[2], model.scene.value(path))


def _slider(model: ViewerModel, name: str, value) -> None:
    c = slider(name)
    flags = imgui.SliderFlags_.always_clamp | (imgui.SliderFlags_.logarithmic if c.log else 0)
    if c.param.value_type == "integer":
        changed, new = imgui.slider_int(name, int(value), int(c.lo), int(c.hi), "%d", flags)
    else:
        changed, new = imgui.slider_float(
            name, float(value), float(c.lo), float(c.hi), c.fmt, flags
        )
    if changed:
        model.set(name, new, slider=True)


def _combo(model: ViewerModel, name: str, value) -> None:
    allowed = combo(name).allowed
    changed, index = imgui.combo(name, allowed.index(value), list(allowed))
    if changed:
        model.set(name, allowed[index])


def _keys(model: ViewerModel) -> str:
    """The keys' help line; P shows the first instrument view (the PMD phase)."""
    first = model.first_views()[:1]
    toggle = "".join(f", P {o.offer.label} {o.view.label}" for o in first)
    return "keys: S screenshot, T save scene, R reset, O overlay" + toggle


def _view_and_readout(model: ViewerModel, status: dict) -> None:
    views = model.view_names()
    changed, index = imgui.combo("view", views.index(model.view), list(views))
    if changed:
        model.view = views[index]
    imgui.separator()
    for line in model.readout_text():
        if not line.startswith("status: "):
            imgui.text_wrapped(line)  # a flagged number's line is long
            continue
        word, _, why = line.removeprefix("status: ").partition(": ")
        ok = word in ("ok", "...", "-")
        colour = imgui.ImVec4(0.6, 0.9, 0.6, 1.0) if ok else imgui.ImVec4(1.0, 0.45, 0.35, 1.0)
        imgui.text_colored(colour, f"status: {word}" + ("" if ok else " (hover: why)"))
        if why and imgui.is_item_hovered():
            imgui.set_tooltip(why.replace("%", "%%"))  # a format string
    if model.readout.folded:
        imgui.text_colored(
            imgui.ImVec4(1.0, 0.6, 0.2, 1.0),
            f"the stripe map folds: {model.readout.islands} islands (not measured)",
        )
    imgui.text_wrapped(status["hover"] or "hover over the image")
    imgui.text(f"last frame {status['frame_ms']:.1f} ms, {model.traces} traces")
    imgui.text_wrapped(_keys(model))
    if status["message"]:
        imgui.text_wrapped(status["message"])
    if model.refused:
        imgui.text_colored(imgui.ImVec4(1.0, 0.45, 0.35, 1.0), model.refused)
