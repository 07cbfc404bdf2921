"""The scene: what the camera sees, as tables of the parameters the components declare.

:mod:`glshade.scene.model` composes the tables and the :class:`Scene`;
:mod:`glshade.scene.paper` builds the paper's scenes. Importing it needs neither OpenCV
nor an OpenGL context.
"""

from glshade.scene.model import (
    Camera,
    Defect,
    Emitter,
    RenderSettings,
    Scene,
    Sensor,
    Surface,
)
from glshade.scene.paper import PAPER_SURFACES, paper_scene

__all__ = [
    "PAPER_SURFACES",
    "Camera",
    "Defect",
    "Emitter",
    "RenderSettings",
    "Scene",
    "Sensor",
    "Surface",
    "paper_scene",
]
