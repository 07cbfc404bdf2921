"""The paper's scene: its camera, emitter and the three surfaces its study runs over."""

from __future__ import annotations

from glshade.errors import SceneError
from glshade.scene.model import Camera, Defect, Emitter, Scene, Surface

#: The paper's three surfaces (its study runs over them).
PAPER_SURFACES: tuple[str, ...] = ("flat", "cylinder", "sphere")
#: Stripe periods the paper uses where they are not the emitter's default (2 mm), mm.
PAPER_PERIOD_MM: dict[str, float] = {"sphere": 10.0}
#: The radius of the paper's cylinder and sphere, mm.
PAPER_RADIUS_MM = 70.0


def paper_scene(
    surface: str = "flat",
    theta_deg: float = 45.0,
    sigma2: float = 4.0,
    dmax: float = 0.005,
    phase: float = 0.0,
) -> Scene:
    """The paper's geometry (Table 1, section III): camera 175.6 mm, emitter 256 mm,
    1024² pixels of 5 µm, f = 25 mm; cylinder and sphere R = 70 mm; sphere period 10 mm."""
    if surface not in PAPER_SURFACES:
        raise SceneError(
            "surface.kind",
            "one of " + ", ".join(PAPER_SURFACES) + " (the paper's surfaces)",
            surface,
        )
    period = PAPER_PERIOD_MM.get(surface, Emitter().period)
    return Scene(
        camera=Camera(theta_deg=theta_deg),
        emitter=Emitter(period=period, phase=phase),
        surface=Surface(kind=surface, radius=PAPER_RADIUS_MM, axis="z"),  # type: ignore[call-arg]
        defect=Defect.isotropic_dent(dmax=dmax, sigma2=sigma2),
    )
