"""The scene: what the camera sees, as tables of parameters declared by the components."""

from glshade.scene.model import (
    PRECISIONS,
    REFLECTIONS,
    SURFACE_KINDS,
    Camera,
    Defect,
    Emitter,
    RenderSettings,
    Scene,
    Surface,
    paper_scene,
)

__all__ = [
    "PRECISIONS",
    "REFLECTIONS",
    "SURFACE_KINDS",
    "Camera",
    "Defect",
    "Emitter",
    "RenderSettings",
    "Scene",
    "Surface",
    "paper_scene",
]
