"""glshade: GPU deflectometry simulator.

A pinhole camera sees a stripe emitter reflected in a flat, cylindrical or spherical
surface carrying a Gaussian dent a few micrometres deep; fragment shaders on a headless
EGL context render the image and the emitter-coordinate (uv) map. Lengths in mm, angles
in degrees. Start with :func:`glshade.scene.paper_scene` and :class:`glshade.renderer.Renderer`.
"""

from .errors import ContextError, GlshadeError, SceneError, ShaderCompileError
from .frame import Frame
from .scene import Camera, Defect, Emitter, RenderSettings, Scene, Surface, paper_scene

__version__ = "0.1.0"

__all__ = [
    "Camera",
    "ContextError",
    "Defect",
    "Emitter",
    "Frame",
    "GlshadeError",
    "RenderSettings",
    "Scene",
    "SceneError",
    "ShaderCompileError",
    "Surface",
    "paper_scene",
    "__version__",
]
