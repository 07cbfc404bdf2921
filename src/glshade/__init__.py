"""glshade: GPU deflectometry simulator.

A pinhole camera sees a stripe emitter reflected in a flat, cylindrical or spherical
surface carrying a Gaussian dent a few micrometres deep; fragment shaders on a headless
EGL context render the image and the emitter-coordinate (uv) map. Lengths in mm, angles
in degrees. Start with :func:`paper_scene`, :class:`Renderer` and :func:`measure`::

    import glshade
    result = glshade.measure(glshade.paper_scene("flat", theta_deg=5, sigma2=1.0, dmax=0.005))
    result.visibility_px, result.visibility_continuous_px, result.deflection_px

Importing ``glshade`` or ``glshade.scene`` and building scenes needs neither OpenGL nor
OpenCV; the ``metrics``, ``oracle`` and ``study`` planning modules need no GL.
:class:`Renderer` and :func:`measure` load ``glshade.gpu`` (and moderngl) on first use,
:class:`MetricSettings` and :class:`Visibility` the metric (and OpenCV).
"""

from glshade.errors import ContextError, GlshadeError, SceneError, ShaderCompileError
from glshade.version import __version__

TYPE_CHECKING = False  # typing's own costs 20 ms; type checkers read this one as True
if TYPE_CHECKING:  # loaded on first use (:func:`__getattr__`), so that ``import glshade``
    # itself is instant: the command line's entry point handles Ctrl-C from its first line
    from glshade.frame import Frame
    from glshade.gpu.renderer import Renderer
    from glshade.metrics.visibility import MetricSettings, Visibility
    from glshade.scene import (
        Camera,
        Defect,
        Emitter,
        RenderSettings,
        Scene,
        Surface,
        paper_scene,
    )

_LAZY = {
    "Frame": ("glshade.frame", "Frame"),
    "Camera": ("glshade.scene", "Camera"),
    "Defect": ("glshade.scene", "Defect"),
    "Emitter": ("glshade.scene", "Emitter"),
    "RenderSettings": ("glshade.scene", "RenderSettings"),
    "Scene": ("glshade.scene", "Scene"),
    "Surface": ("glshade.scene", "Surface"),
    "paper_scene": ("glshade.scene", "paper_scene"),
    "Renderer": ("glshade.gpu.renderer", "Renderer"),
    "MetricSettings": ("glshade.metrics.visibility", "MetricSettings"),
    "Visibility": ("glshade.metrics.visibility", "Visibility"),
}


def __getattr__(name: str):
    """The scene's classes, ``Renderer`` and ``measure`` on first use (the last two need
    moderngl): ``measure`` is the measuring package, callable as
    ``glshade.measure(scene)``."""
    if name == "measure":
        import importlib

        return importlib.import_module("glshade.measure")
    if name in _LAZY:
        import importlib

        module, attribute = _LAZY[name]
        return getattr(importlib.import_module(module), attribute)
    raise AttributeError(f"module 'glshade' has no attribute {name!r}")


__all__ = [
    "Camera",
    "ContextError",
    "Defect",
    "Emitter",
    "Frame",
    "GlshadeError",
    "MetricSettings",
    "RenderSettings",
    "Renderer",
    "Scene",
    "SceneError",
    "ShaderCompileError",
    "Surface",
    "Visibility",
    "__version__",
    "measure",
    "paper_scene",
]
