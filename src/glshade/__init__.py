"""glshade: GPU deflectometry simulator.

A pinhole camera sees a stripe emitter reflected in a flat, cylindrical or spherical
surface carrying a Gaussian dent a few micrometres deep; fragment shaders on a headless
EGL context render the image and the emitter-coordinate (uv) map. Lengths in mm, angles
in degrees. Start with :func:`paper_scene`, :class:`Renderer` and :func:`measure`::

    import glshade
    result = glshade.measure(glshade.paper_scene("flat", theta_deg=5, sigma2=1.0, dmax=0.005))
    result.visibility_px, result.visibility_continuous_px, result.deflection_px
"""

from .errors import ContextError, GlshadeError, SceneError, ShaderCompileError
from .frame import Frame
from .measurement import measure
from .renderer import Renderer
from .scene import Camera, Defect, Emitter, RenderSettings, Scene, Surface, paper_scene
from .visibility import MetricSettings, Visibility

__version__ = "0.1.0"

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
    "measure",
    "paper_scene",
    "__version__",
]
