"""The shape every component has: parameters, shader features, uniforms, GLSL, oracle.

A component is one kind of one *slot* of the scene: the ``cylinder`` of the ``surface``
slot, the ``blinn-phong`` of the ``reflection`` slot. In the spirit of Mitsuba 3's
plugins, it owns, in one module plus its GLSL file(s) under ``shaders/``:

- ``params``: its :class:`~glshade.scene.params.Param` declarations (and ``checks`` over
  several of them);
- ``features(scene)``: the template variables its GLSL needs (the key of the program);
- ``glsl(variables)``: the files it puts into the composed shader, in order;
- ``uniforms(scene, frame)``: every uniform its GLSL declares, computed in float64;
- its NumPy float64 oracle: the functions the reference tracer
  (:mod:`glshade.oracle.tracer`) calls for its slot (listed on each slot's base class
  below).

The renderer, the composer and the tracer loop over the active components of a scene
(:meth:`glshade.components.registry.Registry.active`); none of them knows a kind by name.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from glshade.scene.params import Param, TableCheck

if TYPE_CHECKING:
    from glshade.scene.model import Scene


@dataclass(frozen=True)
class Slot:
    """A place in the scene that one component fills at a time.

    ``table``: the scene table holding its parameters; ``selector``: the parameter whose
    value names the component (``surface.kind``), or None when the slot has one
    component; ``preamble``: its GLSL goes before the outputs' declarations (precision);
    ``oracle``: the base class whose methods the NumPy tracer calls.
    """

    name: str
    table: str
    selector: Param | None
    preamble: bool
    doc: str


@dataclass(frozen=True)
class UniformFrame:
    """What every component's uniforms are computed in: the local frame centred on the
    dent (``origin``, world mm, float64), the composed program's ``variables`` and the
    renderer's dent solver (``march_steps``, ``newton_iterations``, ``tolerance_for``)."""

    origin: np.ndarray
    variables: Mapping[str, Hashable]
    solver: Any


class Component:
    """Base of every component; a subclass sets ``slot`` and ``name`` and overrides what
    it needs. Instances hold no scene state (one instance serves every scene)."""

    slot: ClassVar[str]
    name: ClassVar[str]
    doc: ClassVar[str] = ""
    params: ClassVar[tuple[Param, ...]] = ()
    checks: ClassVar[tuple[TableCheck, ...]] = ()
    #: Where its GLSL files are when they are not under ``shaders/`` (a plug-in's own).
    glsl_dir: ClassVar[Path | None] = None

    def features(self, scene: Scene) -> dict[str, Hashable]:
        """Template variables its GLSL needs; equal features share one program."""
        return {}

    def glsl(self, variables: Mapping[str, Hashable]) -> tuple[str, ...]:
        """The files under ``shaders/`` it contributes, in composition order."""
        return ()

    def uniforms(self, scene: Scene, frame: UniformFrame) -> dict[str, object]:
        """Every uniform its GLSL (for this scene's features) declares, float64 values."""
        return {}

    def textures(self, scene: Scene) -> dict[str, np.ndarray]:
        """Sampler uniform name (``t_…``) -> a float32 array (rows, columns[, channels])
        its GLSL reads with ``texelFetch`` (row = texel y, column = texel x); none by default. The renderer
        uploads each array once (keyed by the array object) and binds it."""
        return {}

    def warnings(self, scene: Scene) -> tuple[str, ...]:
        """Lines about accepted values that will probably not give what was meant (each
        names the field); none by default. Printed by every front end, never fatal."""
        return ()

    def image_from_v(self, scene: Scene) -> bool:
        """True when, as far as this component goes, a pixel's value is the stripe
        radiance at its one mirror ray's ``v``: the metric may then shade every phase from
        the uv map instead of rendering images (a lens, a lobe, Fresnel or a sensor say no)."""
        return True

    def keeps_emitter_scale(self, scene: Scene) -> bool:
        """True when this component leaves the stripes' peak at the emitter's radiance 1,
        so the metric's threshold is a fraction of the emitter peak (SPEC §6); False when
        it scales or mixes the radiance (Fresnel, a microfacet lobe, eq. (1)), and the
        threshold is then taken between the defect-free image's dark and bright levels."""
        return True

    def work_factor(self, scene: Scene) -> int:
        """Rays this component traces per pixel sample (the work budget counts them)."""
        return 1

    def develop(self, scene: Scene, image: np.ndarray, exposure: int = 0) -> np.ndarray:
        """What the sensor makes of a rendered radiance image (float32, in place or new);
        the identity but for the sensor. ``exposure`` numbers independent exposures of
        the same scene (their noise differs)."""
        return image

    def read_file(
        self, values: dict[str, Any], current: dict[str, Any] | None = None
    ) -> dict[str, Any]:
        """Its table's keys as a scene file gives them -> the table's fields (shorthands
        expanded); the identity unless the component has a shorthand. ``current``: the
        table's values the keys change (None when a scene file gives the whole table)."""
        return values

    def write_file(self, values: dict[str, Any]) -> dict[str, Any]:
        """The inverse of :meth:`read_file`, for writing a scene file."""
        return values

    def __repr__(self) -> str:
        return f"<{self.slot} component {self.name!r}>"


# ------------------------------------------------------------------ slot interfaces
class SurfaceComponent(Component):
    """A base surface ``y = f(x, z)`` (SPEC §4). Oracle, all lengths mm, arrays float64:"""

    slot = "surface"

    def domain(self, scene: Scene, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``[t_in, t_out]`` where rays ``o + t d`` ((N, 3) each) are over the domain;
        ``±inf`` when unbounded, NaN when empty."""
        n = len(d)
        return np.full(n, -np.inf), np.full(n, np.inf)

    def band_roots(
        self, scene: Scene, o: np.ndarray, d: np.ndarray, shift: float
    ) -> list[np.ndarray]:
        """Ray parameters where ``y - f = shift`` (every root; spurious ones only add
        breakpoints to the search)."""
        raise NotImplementedError

    def height(self, scene: Scene, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        """``f(x, z)``, clipped to the domain's edge outside it."""
        raise NotImplementedError

    def outside(self, scene: Scene, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        """True where the surface does not exist (its height is NaN)."""
        return np.zeros(np.broadcast(x, z).shape, dtype=bool)

    def normal(
        self, scene: Scene, x: np.ndarray, z: np.ndarray, dx: np.ndarray, dz: np.ndarray
    ) -> np.ndarray:
        """Unnormalised normal (…, 3) of ``f + D`` given the defect's gradient
        ``(D_x, D_z)``; finite wherever the surface exists."""
        raise NotImplementedError

    def second_derivatives(self, scene: Scene) -> tuple[float, float]:
        """``(f_zz, f_xx)`` at the gaze point (1/mm): along the plane of incidence and
        across it; convex is negative (:func:`glshade.metrics.physics.base_curvatures`)."""
        return 0.0, 0.0

    def describe(self, scene: Scene) -> str:
        """The surface in a few words, for figure titles."""
        return self.name


class DefectComponent(Component):
    """A defect ``D(x, z)`` added to the base surface. Oracle:"""

    slot = "defect"

    def present(self, scene: Scene) -> bool:
        return True

    def band(self, scene: Scene) -> tuple[float, float]:
        """``(lo, hi)``: ``D`` lies between them everywhere (mm)."""
        raise NotImplementedError

    def depth(self, scene: Scene, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        """``D(x, z)`` (mm)."""
        raise NotImplementedError

    def gradient(self, scene: Scene, x: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(D_x, D_z)``."""
        raise NotImplementedError

    def breakpoints(self, scene: Scene, o: np.ndarray, d: np.ndarray) -> list[np.ndarray]:
        """Ray parameters where the defect changes character (the search samples each
        stretch between breakpoints densely)."""
        return []

    def centre(self, scene: Scene) -> np.ndarray:
        """The defect's centre ``(x0, 0, z0)`` (world mm): the origin of the local frame."""
        return np.zeros(3)


class CameraComponent(Component):
    """How pixels become rays. Oracle: ``pixel_rays`` (one chief ray per pixel sample)
    and ``sample_rays`` (every ray the shader traces, each with its own origin)."""

    slot = "camera"

    def pixel_rays(
        self, scene: Scene, rows, cols, supersample: int
    ) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def samples(self, scene: Scene) -> int:
        """Rays per pixel sample (a lens's aperture samples); 1 for a pinhole."""
        return 1

    def work_factor(self, scene: Scene) -> int:
        return self.samples(scene)

    def sample_rays(
        self, scene: Scene, rows, cols, supersample: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(origins, directions)``, (h, w, S, 3) each: every ray of each pixel."""
        origin, d = self.pixel_rays(scene, rows, cols, supersample)
        h, w = d.shape[:2]
        d = d.reshape(h, w, supersample * supersample, 3)
        return np.broadcast_to(origin, d.shape), d


class EmitterComponent(Component):
    """The light source. Oracle: ``coordinates`` (where reflected rays land) and
    ``radiance`` (what they see there)."""

    slot = "emitter"

    def coordinates(self, scene: Scene, points, directions):
        raise NotImplementedError

    def radiance(self, scene: Scene, v) -> np.ndarray:
        raise NotImplementedError


class ReflectionComponent(Component):
    """How the surface reflects. Oracle: ``shade``, the pixel value of hits ``p`` seen
    along unit ``d`` with unit normals ``n`` whose mirror rays land at ``v`` (``ok``:
    on the emitter)."""

    slot = "reflection"
    #: The pixel is the emitter's radiance at the mirror ray's ``v``: a picture can be
    #: shaded from the uv map alone (the metric's fast path, the viewer's re-shading).
    shades_from_v: ClassVar[bool] = False

    def image_from_v(self, scene: Scene) -> bool:
        return self.shades_from_v

    def shade(self, scene: Scene, p, d, n, v, ok) -> np.ndarray:
        raise NotImplementedError

    def lobe_std_rad(self, scene: Scene) -> float | None:
        """The angular standard deviation of the reflected direction (rad), or None for
        a perfect mirror. A lobe wider than the stripes can resolve is warned about."""
        return None

    def warnings(self, scene: Scene) -> tuple[str, ...]:
        """A lobe whose footprint on the emitter exceeds half a stripe period washes
        the stripes out (:mod:`glshade.oracle.footprint`)."""
        std = self.lobe_std_rad(scene)
        if std is None:
            return ()
        from glshade.oracle.footprint import footprint_mm

        width = footprint_mm(scene, std)
        period = scene.emitter.period
        if width is None or width <= 0.5 * period:
            return ()
        hint = self.sharpen_hint(scene, width / (0.5 * period))
        line = (
            f"render.reflection = {self.name}: the lobe spreads each point over {width:.3g} mm of the emitter, "
            f"more than half the {period:g} mm stripe period, so the stripes wash out; use {hint} "
            "(docs/physics.md, 'Glossy lobes and stripes')"
        )
        return (line,)

    def sharpen_hint(self, scene: Scene, ratio: float) -> str:
        """What would narrow the lobe ``ratio`` times (for the lobe warning)."""
        return f"a lobe {ratio:.3g} times narrower"


class RenderComponent(Component):
    """How a frame is computed (precision, rays per pixel): the program's preamble."""

    slot = "render"

    def image_from_v(self, scene: Scene) -> bool:
        return scene.render.supersample == 1
