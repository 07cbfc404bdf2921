"""The viewer's controls, generated from the parameter schema.

Every parameter that declares a viewer slider (``Param.control``) is a slider; every
choice (a slot's selector, the cylinder's axis, the precision) is a combo box. A control
is named by its short name (``theta``, ``radius``, the choice's flag without dashes) or
by its dotted path (``camera.theta_deg``); ``--set`` takes either, the same names every
command's ``--set`` takes (:func:`glshade.app.args.setting_param`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from glshade.app.viewer.instrument_view import STRIPE_VIEWS, instrument_views
from glshade.components.registry import registry
from glshade.errors import GlshadeError, SceneError
from glshade.params import Param
from glshade.scene import Scene

if TYPE_CHECKING:
    from glshade.instruments.registry import Instruments


def views(found: Instruments | None = None) -> tuple[str, ...]:
    """The views, in the view menu's order: the viewer's own (the camera image, its
    defect-free twin, the Fig. 9 contour overlay, the displacement), then the maps the
    instruments of ``found`` (default: the registry) offer
    (:func:`glshade.app.viewer.instrument_view.instrument_views`)."""
    return STRIPE_VIEWS + tuple(instrument_views(found))


@dataclass(frozen=True)
class Control:
    """A slider: the parameter it edits (``param.path``) and its range (values are
    clamped to it); ``signed``: the slider sets the magnitude and the sign is kept."""

    name: str
    param: Param
    lo: float
    hi: float
    log: bool = False
    fmt: str = "%.3f"
    signed: bool = False


@dataclass(frozen=True)
class Choice:
    """A combo box over a choice parameter's allowed names."""

    name: str
    param: Param
    allowed: tuple[str, ...]


def controls() -> dict[str, Control]:
    """Short name -> slider, for every parameter that declares one."""
    out = {}
    for param in registry().params():
        c = param.control
        if c is not None:
            out[c.name] = Control(c.name, param, c.lo, c.hi, c.log, c.fmt, c.signed)
    return out


def choices() -> dict[str, Choice]:
    """Short name -> combo box, for every choice parameter."""
    out = {}
    for param in registry().params():
        if param.value_type == "choice":
            name = param.flag.lstrip("-") if param.flag else param.key
            out[name] = Choice(name, param, registry().choices(param) or param.choices)
    return out


#: The viewer's own settings, besides the scene's: what it shows, and the surface's
#: concave checkbox.
VIEWER_SETTINGS = ("view", "animate", "pmd_size", "concave")


def by_name(name: str) -> Control | Choice | None:
    """The control of the parameter called ``name`` (a short name or a dotted path, as
    every command's ``--set`` resolves it); None where it names no control."""
    from glshade.app.args import setting_param

    try:
        param = setting_param(name)
    except GlshadeError:
        return None
    return _control_of(param)


def _control_of(param: Param) -> Control | Choice | None:
    for table in (controls(), choices()):
        for control in table.values():
            if control.param.path == param.path:
                return control
    return None


def slider(name: str) -> Control:
    """The slider called ``name`` (a KeyError when it is not one)."""
    control = by_name(name)
    if not isinstance(control, Control):
        raise KeyError(f"no slider {name!r}")
    return control


def combo(name: str) -> Choice:
    """The combo box called ``name`` (a KeyError when it is not one)."""
    control = by_name(name)
    if not isinstance(control, Choice):
        raise KeyError(f"no combo box {name!r}")
    return control


def clamp(control: Control, value: float) -> float:
    value = min(max(float(value), control.lo), control.hi)
    return round(value) if control.param.value_type == "integer" else value


def _constrained(scene: Scene, path: str, value: float) -> float:
    """Keep a slider inside what the scene accepts: its table's joint constraints (a
    covariance positive definite, a stripe no wider than half a period)."""
    table, _, key = path.partition(".")
    return getattr(scene, table).clamp(key, value)


def apply_setting(scene: Scene, name: str, value, slider: bool = False) -> Scene:
    """The scene with one viewer setting changed, validated by the scene model exactly
    as ``render`` validates it (a SceneError names the field and the allowed range).
    ``slider``: the value comes from dragging a slider, and is kept inside the slider's
    range and the scene's joint constraints (a positive definite covariance)."""
    if name == "concave":
        radius = abs(scene.value("surface.radius"))
        return scene.with_value("surface.radius", -radius if bool(value) else radius)
    from glshade.app.args import setting_param

    param = setting_param(name, VIEWER_SETTINGS)  # one line for an unknown or ambiguous name
    control = _control_of(param)
    if control is None:  # a parameter without a control: taken as typed
        return scene.with_value(param.path, value)
    path = control.param.path
    if isinstance(control, Choice):
        if value not in control.allowed:
            raise SceneError(path, "one of " + ", ".join(control.allowed), value)
        return scene.with_value(path, value)
    if slider:
        value = _constrained(scene, path, clamp(control, value))
    if control.signed:
        value = math.copysign(value, scene.value(path))
    return scene.with_value(path, value)


def parse_sets(
    items: list[str], scene: Scene, size: int | None = None, default_size: int | None = None
) -> tuple[Scene, dict[str, str]]:
    """``--set name=value`` items: scene settings are parsed and applied exactly as
    ``render``'s ``--set`` applies them, with ``--size`` (``size``, else ``default_size``
    unless ``camera.width`` is typed; :func:`glshade.app.args.with_settings`: a short
    name or a dotted path, lengths with a unit, ``dmax=5um``, all at once); the viewer's
    own (``view``, ``animate``, ``pmd_size``) are returned, and ``concave`` turns the
    final radius inwards. A bad value is named as typed: ``--set sigma2
    (defect.sigma2): ...``."""
    from glshade.app.args import named_as_typed, with_settings

    extra: dict[str, str] = {}
    settings: list[str] = []
    concave: str | None = None
    for item in items:
        name, sep, raw = item.partition("=")
        name = name.strip()
        if not sep or not name:
            raise GlshadeError(f"--set {item!r}: expected name=value")
        if name == "view":
            known = views()
            if raw not in known:
                raise GlshadeError(f"--set view: must be one of {', '.join(known)}, got {raw!r}")
            extra[name] = raw
        elif name in ("animate", "pmd_size"):
            extra[name] = raw
        elif name == "concave":
            concave = raw
        else:
            settings.append(item)
    scene = with_settings(scene, settings, VIEWER_SETTINGS, size, default_size)
    if concave is not None:
        with named_as_typed({"surface.radius": "--set concave"}):
            scene = apply_setting(scene, "concave", concave.lower() in ("1", "true", "yes"))
    if "pmd_size" in extra:
        extra["pmd_size"] = str(_pmd_size(extra["pmd_size"], scene))
    return scene, extra


def _pmd_size(raw: str, scene: Scene) -> int:
    """``--set pmd_size=N``: pixels across an instrument view's case (the PMD views'),
    16 to the image's width."""
    width = scene.camera.width
    try:
        size = int(raw)
    except ValueError:
        size = -1
    if not 16 <= size <= width:
        raise GlshadeError(f"--set pmd_size: must be an integer in [16, {width}], got {raw!r}")
    return size


def geometry_key(scene: Scene) -> Scene:
    """What a trace depends on: everything but the phase."""
    return scene.with_phase(0.0)


def panel_params(scene: Scene) -> list[Param]:
    """The parameters the panel shows for ``scene``: the selectors, and the parameters of
    the components in use that have a control or are a text (a formula, a file path), in
    the schema's order. A quiet one (a pose's mode) only where the scene changes it: the
    rig's panel stays the rig's."""
    reg = registry()
    active = set(reg.active(scene))
    shown = []
    for param in reg.params():
        if param.control is None and param.value_type not in ("choice", "text", "path"):
            continue
        if param.quiet and scene.value(param.path) == param.default:
            continue
        if reg.choices(param) is not None or any(owner in active for owner in reg.owners(param)):
            shown.append(param)
    return shown
