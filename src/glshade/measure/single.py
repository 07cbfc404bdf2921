"""Measuring one scene with any registered instrument: ``glshade.measure(scene)``.

The instrument is chosen by name (``method``) or, when none is named, by the scene's
emitter (the one that measures it: stripes are binarised, fringes decoded); it is taken
from the registry (:mod:`glshade.instruments.registry`), so a plug-in's instrument is
measured exactly as glshade's own.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any

from glshade.errors import GlshadeError
from glshade.instruments.registry import instrument, method_names
from glshade.scene import Scene

if TYPE_CHECKING:
    from glshade.rendering import Renderer


def method_for(scene: Scene, method: str | None) -> str:
    """The instrument to measure ``scene`` with: ``method`` itself (a registered name), or
    the one its emitter is measured by when None."""
    if method is None:
        return scene.active.emitter.measured_by
    return instrument(method).name


def as_method(scene: Scene, method: str) -> Scene:
    """The scene as instrument ``method`` measures it
    (:meth:`~glshade.instruments.base.Instrument.prepared`)."""
    return instrument(method).prepared(scene)


def methods() -> tuple[str, ...]:
    """The registered instruments' names (``--method`` choices)."""
    return method_names()


def measure(
    scene: Scene | str | os.PathLike[str],
    *,
    renderer: Renderer | None = None,
    settings: Any = None,
    overlay: str | os.PathLike[str] | None = None,
    method: str | None = None,
    pmd_settings: Any = None,
) -> Any:
    """How visible is this scene's defect? ``glshade.measure(paper_scene("flat", 5, 1.0, 0.005))``.

    ``method``: the instrument (``paper``, ``pmd`` or a plug-in's; default: the one the
    scene's emitter is measured by); ``settings``: that instrument's settings (default:
    its defaults; ``pmd_settings`` is another name for them). The paper's stripe metric
    returns a :class:`glshade.metrics.visibility.Visibility` (``visibility_px``, its
    continuous limit, ``deflection_px``, ...; ``overlay``: also write the Fig. 9 overlay
    there, a PNG); phase measuring a :class:`glshade.instruments.pmd.measure.PmdResult`.
    Each result's table row is its instrument's ``record(scene, result)``. Creates (and
    releases) a renderer unless one is given; ``scene`` may be the path of a scene file.
    Bad input raises a :class:`~glshade.errors.GlshadeError` with one line, before any
    rendering.
    """
    scene = _scene(scene)
    chosen = instrument(method_for(scene, method))
    if pmd_settings is not None:
        if settings is not None:
            raise GlshadeError("settings and pmd_settings: give one of them")
        settings = pmd_settings
    settings = chosen.settings() if settings is None else settings
    if type(settings) is not chosen.settings_type:
        raise GlshadeError(
            f"settings: method {chosen.name!r} is measured with "
            f"{chosen.settings_type.__name__}, got {type(settings).__name__}"
        )
    scene = chosen.prepared(scene)
    chosen.check_case(scene, settings)
    if overlay is not None:
        return _with_overlay(chosen, scene, settings, overlay, renderer)
    if renderer is not None:
        return chosen.measure(renderer, scene, settings)
    from glshade.gpu.renderer import Renderer as GlRenderer

    with GlRenderer() as own:
        return chosen.measure(own, scene, settings)


def _with_overlay(
    chosen: Any, scene: Scene, settings: Any, overlay: Any, renderer: Renderer | None
) -> Any:
    """The measurement with the instrument's ``--overlay`` file written to ``overlay``
    (the stripe metric's Fig. 9 contour overlay)."""
    option = next((o for o in chosen.file_options if o.flag == "--overlay"), None)
    if option is None:
        raise GlshadeError(f"overlay: method {chosen.name!r} draws no contour overlay")
    from glshade.files import check_output

    check_output(overlay, "overlay", option.suffixes)
    files = {"--overlay": overlay}
    if renderer is not None:
        return chosen.measure_files(renderer, scene, settings, files)
    from glshade.gpu.renderer import Renderer as GlRenderer

    with GlRenderer() as own:
        return chosen.measure_files(own, scene, settings, files)


def _scene(scene: Any) -> Scene:
    if isinstance(scene, (str, os.PathLike)):
        scene = Scene.load(scene)
    if not isinstance(scene, Scene):
        raise GlshadeError(
            "scene: must be a glshade Scene or the path of a scene file, got "
            f"{type(scene).__name__}"
        )
    return scene
