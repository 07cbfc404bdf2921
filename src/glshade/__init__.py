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
from glshade.frame import Frame
from glshade.scene import (
    Camera,
    Defect,
    Emitter,
    RenderSettings,
    Scene,
    Surface,
    paper_scene,
)

__version__ = "0.1.0"

_LAZY = {
    "Renderer": ("glshade.gpu.renderer", "Renderer"),
    "MetricSettings": ("glshade.metrics.visibility", "MetricSettings"),
    "Visibility": ("glshade.metrics.visibility", "Visibility"),
}


def __getattr__(name: str):
    """``Renderer`` and ``measure`` on first use (they need moderngl): ``measure`` is the
    measuring package, callable as ``glshade.measure(scene)``."""
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
