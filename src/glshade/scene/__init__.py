"""The scene: what the camera sees, as tables of the parameters the components declare.

:mod:`glshade.scene.params` declares what a parameter is; :mod:`glshade.scene.model`
builds the tables and the :class:`Scene` from the registered declarations.
"""

from glshade.scene.model import (
    PAPER_SURFACES,
    Camera,
    Defect,
    Emitter,
    RenderSettings,
    Scene,
    Sensor,
    Surface,
    Table,
    paper_scene,
)

__all__ = [
    "PAPER_SURFACES",
    "Camera",
    "Defect",
    "Emitter",
    "RenderSettings",
    "Scene",
    "Sensor",
    "Surface",
    "Table",
    "paper_scene",
]
