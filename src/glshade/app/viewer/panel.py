"""The viewer's control panel (imgui): the controls of the components in use, generated
from the parameter schema (:func:`glshade.app.viewer.controls.panel_params`), then the
view, the readout and the help line."""

from __future__ import annotations

import math

from imgui_bundle import imgui

from glshade.app.viewer.controls import VIEWS, combo, panel_params, slider
from glshade.app.viewer.model import ViewerModel, readout_lines
from glshade.params import Param

PANEL_WIDTH = 360
#: The panel lists the tables in this order (the surface first: it changes the most).
PANEL_TABLES = ("surface", "camera", "defect", "emitter", "render", "sensor")
#: Parameters drawn by a dedicated widget rather than a plain slider.
_SHORTHAND = "defect.sigma2"
_COVARIANCE = ("defect.sigma_x2", "defect.sigma_z2", "defect.sigma_xz")


def draw_panel(model: ViewerModel, left: int, height: int, status: dict) -> None:
    """One frame of the panel at ``x = left``; ``status``: hover text, message, scale."""
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
    imgui.end()
    imgui.render()


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


def _view_and_readout(model: ViewerModel, status: dict) -> None:
    changed, index = imgui.combo("view", VIEWS.index(model.view), list(VIEWS))
    if changed:
        model.view = VIEWS[index]
    imgui.separator()
    for line in readout_lines(model.readout):
        imgui.text(line)
    if model.readout.folded:
        imgui.text_colored(
            imgui.ImVec4(1.0, 0.6, 0.2, 1.0),
            f"the stripe map folds: {model.readout.islands} islands (not measured)",
        )
    if model.view == "displacement":
        imgui.text(f"colour scale: 0 (dark) to {status['scale_top']:.2f} px (yellow)")
    imgui.text_wrapped(status["hover"] or "hover over the image")
    imgui.text(f"{imgui.get_io().framerate:.0f} fps, {model.traces} traces")
    imgui.text_wrapped("keys: S screenshot, T save scene, R reset, O overlay")
    if status["message"]:
        imgui.text_wrapped(status["message"])
    if model.refused:
        imgui.text_colored(imgui.ImVec4(1.0, 0.45, 0.35, 1.0), model.refused)
