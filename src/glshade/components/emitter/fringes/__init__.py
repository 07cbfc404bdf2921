"""The fringe emitter: a screen on the stripes' plane showing one frame of a
phase-shifted sinusoidal fringe sequence (phase-measuring deflectometry).

Table: :class:`~glshade.components.emitter.fringes.table.FringesTable`, its coding the
:class:`~glshade.components.emitter.fringes.codec.FringeCodec` (the uniforms' values and
the oracle's formula). GLSL: ``lib/emitter_plane.glsl`` (the plane, shared with the
stripes) and ``fringes.glsl`` (the frame's radiance). Oracle: :meth:`Fringes.coordinates`
(the plane's) and :meth:`Fringes.radiance`. The paper's stripe metric is not defined for
fringes: :meth:`Fringes.pattern` refuses.
"""

from __future__ import annotations

import math
from collections.abc import Hashable, Mapping
from typing import Any, NoReturn, cast

import numpy as np

from glshade.components.base import EmitterComponent, SceneView, UniformContext
from glshade.components.emitter import plane
from glshade.components.emitter.fringes.table import DIRECTIONS, FringeFrame, FringesTable
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
    pattern_noun = "fringe"

    def features(self, scene: SceneView) -> dict[str, Hashable]:
        em = self.frame(scene)
        return {
            "cover_glass": em.glass_thickness > 0.0,
            "screen_sag": plane.sag_of(scene) is not None,
            "fringe_pixels": em.pixel_pitch > 0.0,
            "fringe_response": "curve" if em.response_file is not None else "gamma",
        }

    def glsl(self, variables: Mapping[str, Hashable]) -> tuple[str, ...]:
        if not variables["shading"]:
            return ("lib/emitter_plane.glsl",)
        kernels = ("lib/kernels.glsl",) if variables["filtered"] else ()
        return ("lib/emitter_plane.glsl", *kernels, "fringes.glsl")

    def uniforms(self, scene: SceneView, context: UniformContext) -> dict[str, object]:
        values = plane.uniforms(scene, context)
        em = self.frame(scene)
        if em.glass_thickness > 0.0:
            values.update(
                u_emitter_glass_thickness=em.glass_thickness, u_emitter_glass_index=em.glass_index
            )
        variables = context.variables
        if not variables["shading"]:
            return values
        codec = em.codec
        screen = codec.screen()
        outputs = cast("tuple[str, ...]", variables["outputs"])
        patterns = context.frames if "frames" in outputs else (em.shown(),)
        values.update(
            u_emitter_fringe_levels=float(codec.levels),
            u_emitter_fringe_step=codec.level_step,
            u_emitter_fringe_floor=screen.floor,
            u_emitter_fringe_gain=screen.gain,
            u_emitter_frame=[(float(f.axis), f.shift_rad, f.offset, f.amplitude) for f in patterns],
            u_emitter_frame_period=[f.period_mm for f in patterns],
        )
        if screen.curve is None:
            values["u_emitter_fringe_gamma"] = codec.gamma
        if em.pixel_pitch > 0.0:
            values.update(
                u_emitter_pixel_pitch=em.pixel_pitch,
                u_emitter_pixel_lit=0.5 * math.sqrt(em.fill_factor) * em.pixel_pitch,
                u_emitter_ambient=em.ambient,
            )
            if variables["filtered"]:
                values["u_emitter_footprint_samples"] = em.footprint_samples
        if variables["filtered"] or variables["diffuse"]:
            series = [shader_series(em, f) for f in patterns]
            values["u_emitter_harmonics"] = [
                tuple(float(b) for b in s[start : start + 4]) for s in series for start in (0, 4)
            ]
        return values

    def textures(self, scene: SceneView) -> dict[str, np.ndarray]:
        em = self.frame(scene)
        if em.response_file is None:
            return {}
        curve = em.screen().curve
        assert curve is not None
        return {"t_emitter_response": curve.texture}

    def pattern_loop_iterations(self, scene: SceneView, solver: Any) -> int:
        # per pattern shaded: its harmonics through a lobe (7), or the kernel's points over a
        # pixelated screen; the diffuse part's harmonics times its stretches (7 x 24)
        variables = scene.active.features(scene)
        em = self.frame(scene)
        count = 0
        if variables.get("filtered"):
            count += em.footprint_samples + 1 if em.pixel_pitch > 0.0 else 8
        if variables.get("diffuse"):
            count += 8 * 25
        return count

    def loop_iterations(self, scene: SceneView, solver: Any) -> int:
        # once per hit: the diffuse part's marginals (25 x 8 Gauss points) and polygon
        return 25 * 9 + 1 + 6 if scene.active.features(scene).get("diffuse") else 0

    def sequence(self, scene: SceneView) -> tuple[FringeFrame, ...]:
        """The coding's frames (:meth:`FringesTable.sequence`)."""
        return self.frame(scene).sequence()

    def white(self, scene: SceneView) -> FringeFrame:
        return self.frame(scene).white()

    def showing(self, scene: SceneView, frame: FringeFrame) -> SceneView:
        """The scene showing ``frame`` (its ``frame_*`` values, or the white screen's)."""
        return scene.updated(emitter=self.frame(scene).showing(frame))

    def exposure_scene(self, scene: SceneView) -> SceneView:
        """The screen's brightest level over the whole screen: ``"auto"`` exposes every
        frame of the sequence alike, for the brightest the screen displays."""
        top = self.frame(scene).codec.peak_commanded
        return scene.updated(emitter={"offset": top, "amplitude": 0.0})

    @staticmethod
    def frame(scene: SceneView) -> FringesTable:
        """The scene's emitter table, as the fringes read it."""
        return cast(FringesTable, scene.emitter)

    def pattern(self, scene: SceneView) -> NoReturn:
        raise GlshadeError(NO_STRIPE_METRIC)

    def pattern_axes(self, scene: SceneView) -> tuple[int, ...]:
        """The sequence's directions: ``u`` (0) and ``v`` (1) as coded."""
        return tuple(sorted(DIRECTIONS.index(d) ^ 1 for d in self.frame(scene).directions))

    def finest_period_mm(self, scene: SceneView) -> float:
        return self.frame(scene).periods[0]

    def radiance_step(self, scene: SceneView) -> float:
        return self.frame(scene).largest_step()

    def feature_mm(self, scene: SceneView) -> float:
        """A sinusoid changes over ``period / 2π``; a pixelated screen's pixels and its
        black matrix over their own widths."""
        em = self.frame(scene)
        finest = em.frame_period / (2.0 * math.pi)
        if em.pixel_pitch:
            edge = 0.5 * (1.0 - math.sqrt(em.fill_factor)) * em.pixel_pitch
            finest = min(finest, em.pixel_pitch, *((edge,) if edge > 0.0 else ()))
        return finest

    # ------------------------------------------------------------------ oracle
    def cover_glass(self, scene: SceneView) -> tuple[float, float] | None:
        """The screen's cover glass ``(thickness mm, index)``, None without one."""
        em = self.frame(scene)
        return (em.glass_thickness, em.glass_index) if em.glass_thickness > 0.0 else None

    def jacobian(
        self,
        scene: SceneView,
        points: np.ndarray,
        r: np.ndarray,
        a1: np.ndarray,
        a2: np.ndarray,
    ) -> np.ndarray:
        """The plane's (:func:`glshade.components.emitter.plane.jacobian`)."""
        return plane.jacobian(scene, points, r, a1, a2, self.cover_glass(scene))

    def coordinates(
        self, scene: SceneView, points: np.ndarray, directions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Where rays meet the screen's emitting layer (through its cover glass):
        :func:`glshade.components.emitter.plane.coordinates`."""
        return plane.coordinates(scene, points, directions, self.cover_glass(scene))

    def along(self, scene: SceneView, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        return u if self.frame(scene).axis == 0 else v

    def radiance(self, scene: SceneView, v: np.ndarray) -> np.ndarray:
        """The frame's displayed radiance at the screen coordinate along its direction
        (``v`` for a ``"v"`` frame, ``u`` for a ``"u"`` frame: :meth:`along`) of a
        continuous screen."""
        return self.frame(scene).fringe_radiance(v)

    def radiance_uv(self, scene: SceneView, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The frame's displayed radiance at screen points ``(u, v)``, on the screen's
        pixels where it has a pitch (:meth:`FringesTable.radiance_uv`)."""
        return self.frame(scene).radiance_uv(u, v)

    def diffuse(self, scene: SceneView, p: np.ndarray, n: np.ndarray) -> np.ndarray:
        """The Lambertian radiance of the frame shown at hits ``p`` with unit normals ``n``:
        ``(1/π) ∫ L cos θs cos θe / r² dA`` over the screen, by brute force: the kernel
        integrated across the fringes by Gauss–Legendre (48 points) at midpoints along them
        at least 16 a period. A pixelated screen is taken as its pixels average (the fill
        factor's share of the fringe, the ambient light between: the kernel spans hundreds of
        pixels)."""
        em = self.frame(scene)
        frame = em.shown()
        axis = frame.axis
        extent = 2.0 * em.half_size[axis]
        count = int(max(400, math.ceil(16.0 * extent / frame.period_mm)))
        s = (np.arange(count) + 0.5) * extent / count  # from the screen's edge
        values = em.codec.frame_radiance(frame, s)
        if em.pixel_pitch:
            values = em.ambient + em.fill_factor * (values - em.ambient)
        x, w = np.polynomial.legendre.leggauss(48)
        across = x * em.half_size[1 - axis]
        along = s - em.half_size[axis]
        coords = (
            (along[:, None], across[None, :]) if axis == 0 else (across[None, :], along[:, None])
        )
        plane_ = scene.emitter_plane()
        points = (
            plane_.centre + coords[0][..., None] * plane_.e_u + coords[1][..., None] * plane_.e_v
        )
        weights = (w * em.half_size[1 - axis])[None, :] * (extent / count)  # (1, 48)
        out = np.empty(len(p))
        for i in range(len(p)):
            kernel = plane.lambert_kernel(plane_, points - p[i], n[i])  # (along, across)
            marginal = np.sum(kernel * weights, axis=1)
            out[i] = np.sum(marginal * values) / math.pi
        return out


#: Harmonics of a displayed fringe below this share of the screen's white are left out of
#: the shader's series (each costs every ray a transfer or a Lambert integral per pattern):
#: a 256-level screen's rounding puts 3e-5 to 4e-5 of the white into b_3, b_5 and b_7,
#: which a lobe or the diffuse kernel then weighs by at most 1.
SERIES_FLOOR = 1e-4


def shader_series(em: FringesTable, frame: FringeFrame) -> np.ndarray:
    """``frame``'s cosine series ``b_0 … b_7`` (:meth:`FringesTable.harmonics`) as the
    shader keeps it: ``b_0`` always, the harmonics above :data:`SERIES_FLOOR` of the white."""
    series = em.harmonics(frame)
    white = float(em.screen().displayed(np.array(1.0)))
    tiny = np.abs(series) < SERIES_FLOOR * white
    tiny[0] = False
    series[tiny] = 0.0
    return series


COMPONENTS = (Fringes,)
