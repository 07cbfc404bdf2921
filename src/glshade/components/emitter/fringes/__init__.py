"""The fringe emitter: a screen on the stripes' plane showing one frame of a
phase-shifted sinusoidal fringe sequence (phase-measuring deflectometry).

Table: :class:`~glshade.components.emitter.fringes.table.FringesTable`. GLSL:
``lib/emitter_plane.glsl`` (the plane, shared with the stripes) and ``fringes.glsl`` (the
frame's radiance). Oracle: :meth:`Fringes.coordinates` (the plane's) and
:meth:`Fringes.radiance`. The paper's stripe metric is not defined for fringes:
:meth:`Fringes.pattern` refuses.
"""

from __future__ import annotations

from glshade.components.base import EmitterComponent
from glshade.components.emitter import plane
from glshade.components.emitter.fringes.table import FringeFrame, FringesTable
from glshade.errors import GlshadeError

#: Why a fringe scene has no stripe metric.
NO_STRIPE_METRIC = (
    'the paper\'s stripe metric needs emitter.kind = "stripes"; '
    "phase decoding of fringes is measured separately"
)


class Fringes(EmitterComponent):
    name = "fringes"
    rank = 200
    doc = "a screen showing one frame of phase-shifted sinusoidal fringes (phase measuring)"
    table = FringesTable
    measured_by = "pmd"

    def glsl(self, variables):
        outputs = variables["outputs"]
        if "image" not in outputs and "frames" not in outputs:
            return ("lib/emitter_plane.glsl",)
        if variables["blur"] != "none" or variables["diffuse"]:
            raise GlshadeError(
                'emitter.kind = "fringes" is rendered with render.reflection = "mirror" '
                "and no coherence term (its lobes and diffuse part are the stripes' only)"
            )
        return ("lib/emitter_plane.glsl", "fringes.glsl")

    def uniforms(self, scene, context):
        values = plane.uniforms(scene, context)
        outputs = context.variables["outputs"]
        em = self.frame(scene)
        if "image" in outputs or "frames" in outputs:
            values.update(u_emitter_fringe_gamma=em.gamma, u_emitter_fringe_levels=float(em.levels))
        if "image" in outputs:
            axis = (1.0, 0.0) if em.axis == 0 else (0.0, 1.0)
            values.update(
                u_emitter_fringe_axis=axis,
                u_emitter_fringe_period=em.frame_period,
                u_emitter_fringe_step=em.frame_step,
                u_emitter_fringe_offset=em.offset,
                u_emitter_fringe_amplitude=em.amplitude,
            )
        if "frames" in outputs:
            frames = context.frames
            values.update(
                u_emitter_frame=[
                    (float(f.axis), f.shift_rad, f.offset, f.amplitude) for f in frames
                ],
                u_emitter_frame_period=[f.period_mm for f in frames],
            )
        return values

    def sequence(self, scene) -> tuple[FringeFrame, ...]:
        """The coding's frames (:meth:`FringesTable.sequence`)."""
        return self.frame(scene).sequence()

    def white(self, scene) -> FringeFrame:
        return self.frame(scene).white()

    def showing(self, scene, frame: FringeFrame):
        """The scene showing ``frame`` (its ``frame_*`` values, or the white screen's)."""
        return scene.updated(emitter=self.frame(scene).showing(frame))

    def exposure_scene(self, scene):
        """The screen's brightest level over the whole screen: ``"auto"`` exposes every
        frame of the sequence alike, for the brightest the screen displays."""
        em = self.frame(scene)
        top = min(1.0, em.offset + em.amplitude)
        return scene.updated(emitter={"offset": top, "amplitude": 0.0})

    @staticmethod
    def frame(scene) -> FringesTable:
        """The scene's emitter table, as the fringes read it."""
        return scene.emitter

    def pattern(self, scene):
        raise GlshadeError(NO_STRIPE_METRIC)

    def finest_period_mm(self, scene) -> float:
        return self.frame(scene).periods[0]

    def radiance_step(self, scene) -> float:
        return self.frame(scene).largest_step()

    # ------------------------------------------------------------------ oracle
    def coordinates(self, scene, points, directions):
        """Where rays meet the screen: :func:`glshade.components.emitter.plane.coordinates`."""
        return plane.coordinates(scene, points, directions)

    def along(self, scene, u, v):
        return u if self.frame(scene).axis == 0 else v

    def radiance(self, scene, v):
        """The frame's displayed radiance at the screen coordinate along its direction
        (``v`` for a ``"v"`` frame, ``u`` for a ``"u"`` frame: :meth:`along`)."""
        return self.frame(scene).fringe_radiance(v)

    def radiance_uv(self, scene, uv):
        """The frame's displayed radiance at screen points ``uv`` (…, 2) mm."""
        em = self.frame(scene)
        return em.fringe_radiance(uv[..., em.axis])


COMPONENTS = (Fringes,)
