"""The shape every component has: parameters, shader features, uniforms, GLSL, oracle.

A component is one kind of one *slot* of the scene: the ``cylinder`` of the ``surface``
slot, the ``blinn-phong`` of the ``reflection`` slot. In the spirit of Mitsuba 3's
plugins, it is one folder (``components/<slot>/<name>/``) that owns:

- ``table``: its parameters, a frozen dataclass whose fields are declared with
  :func:`glshade.params.param` (unit, default, range, role); ``params`` lists them;
- ``features(scene)``: the template variables its GLSL needs (the key of the program);
- ``glsl(variables)``: its GLSL files (beside its module; ``lib/...``: the shared
  library under ``shaders/lib``), which define what its slot's header under
  ``shaders/slots`` declares;
- ``uniforms(scene, context)``: every uniform its GLSL declares, computed in float64,
  each named ``u_<slot>_...`` (its slot's namespace);
- its NumPy float64 oracle: the methods its slot's base class below lists;
- ``docs.md`` (optional): its paragraph of ``docs/scene-format.md``;
- ``accuracy.py`` (optional): its accuracy knob (:meth:`Component.accuracy_knob`).

The renderer, the composer and the tracer ask a scene's :class:`Active` components (the
scene resolves them once, ``scene.active``); none of them knows a kind by name.
"""

from __future__ import annotations

import inspect
from collections.abc import Hashable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np

from glshade.params import Param, Table, declared_params
from glshade.rig import CameraPose, EmitterPlane, Gaze

if TYPE_CHECKING:  # the scene's tables, as the components that own them declare them
    from glshade.components.accuracy import AccuracyKnob
    from glshade.components.camera.perspective.table import Camera
    from glshade.components.defect.gaussian.table import Defect
    from glshade.components.emitter.stripes.table import Emitter
    from glshade.components.render.table import RenderTable
    from glshade.components.sensor.linear.table import Sensor
    from glshade.components.surface.table import SurfaceTable


@dataclass(frozen=True)
class Slot:
    """A place in the scene that one component fills at a time.

    ``table``: the scene table holding its parameters; ``selector``: the parameter whose
    value names the component (``surface.kind``), or None when the slot has one
    component; ``preamble``: its GLSL goes before the outputs' declarations (precision);
    ``header``: the file under ``shaders/slots`` that declares what its component's GLSL
    must define (None: no GLSL).
    """

    name: str
    table: str
    selector: Param | None
    preamble: bool
    doc: str
    header: str | None = None

    @property
    def uniform_prefix(self) -> str:
        """Every uniform of the slot's components is named ``u_<slot>_...``."""
        return f"u_{self.name}_"

    @property
    def texture_prefix(self) -> str:
        """Every texture (sampler) of the slot's components is named ``t_<slot>_...``."""
        return f"t_{self.name}_"


@dataclass(frozen=True)
class UniformContext:
    """What every component's uniforms are computed in: the local frame centred on the
    dent (``origin``, world mm, float64), the composed program's ``variables``, the
    renderer's dent solver (``march_steps``, ``newton_iterations``, ``tolerance_for``) and,
    for a stack of emitter frames (the ``frames`` output), the frames of the draw, which
    the emitter describes (:meth:`EmitterComponent.sequence`)."""

    origin: np.ndarray
    variables: Mapping[str, Hashable]
    solver: Any
    frames: tuple[Any, ...] = ()


class SceneView(Protocol):
    """What a component reads of a scene: its tables, the emitter's plane, the local
    frame's origin, the scene as a file writes it, its active components, and a copy
    with some keys of some tables replaced."""

    @property
    def camera(self) -> Camera: ...
    @property
    def emitter(self) -> Emitter: ...
    @property
    def surface(self) -> SurfaceTable: ...
    @property
    def defect(self) -> Defect: ...
    @property
    def render(self) -> RenderTable: ...
    @property
    def sensor(self) -> Sensor: ...
    @property
    def active(self) -> Active: ...

    def emitter_plane(self) -> EmitterPlane: ...
    def camera_pose(self) -> CameraPose: ...
    @property
    def gaze(self) -> Gaze: ...

    def local_origin(self) -> np.ndarray: ...

    def to_dict(self) -> dict[str, dict[str, Any]]: ...

    def updated(self, **tables: dict[str, Any]) -> SceneView: ...


class Component:
    """Base of every component; a subclass sets ``slot``, ``name`` and (when it has
    parameters) ``table``, and overrides what it needs. Instances hold no scene state
    (one instance serves every scene)."""

    slot: ClassVar[str]
    name: ClassVar[str]
    doc: ClassVar[str] = ""
    #: Its place among its slot's components (in lists of names, docs and flags).
    rank: ClassVar[int] = 100
    #: Its parameters: a :class:`~glshade.params.Table` dataclass (None: none).
    table: ClassVar[type[Table] | None] = None
    #: Scene-file keys that are not fields but set some (``defect.sigma2``), each with the
    #: field it is listed before.
    shorthands: ClassVar[tuple[tuple[Param, str], ...]] = ()
    #: Where its GLSL files are (default: its module's folder).
    glsl_dir: ClassVar[Path | None] = None

    @classmethod
    def declared(cls) -> tuple[Param, ...]:
        """Every parameter it declares: its table's fields, each shorthand before the
        field it names."""
        out: list[Param] = []
        for field in declared_params(cls.table) if cls.table is not None else ():
            out += [short for short, before in cls.shorthands if before == field.key]
            out.append(field)
        return tuple(out)

    @cached_property
    def params(self) -> tuple[Param, ...]:
        return self.declared()

    def glsl_folder(self) -> Path:
        """The folder its GLSL file names are relative to."""
        return (
            self.glsl_dir if self.glsl_dir is not None else Path(inspect.getfile(type(self))).parent
        )

    def docs(self) -> str:
        """Its paragraph of ``docs/scene-format.md``: ``docs.md`` beside its module, if any."""
        path = self.glsl_folder() / "docs.md"
        return path.read_text(encoding="utf-8").strip() if path.is_file() else ""

    def features(self, scene: SceneView) -> dict[str, Hashable]:
        """Template variables its GLSL needs; equal features share one program."""
        return {}

    def glsl(self, variables: Mapping[str, Hashable]) -> tuple[str, ...]:
        """Its GLSL files, in composition order: names relative to :meth:`glsl_folder`,
        or ``lib/...`` for the shared library."""
        return ()

    def uniforms(self, scene: SceneView, context: UniformContext) -> dict[str, object]:
        """Every uniform its GLSL (for this scene's features) declares, float64 values,
        named in its slot's namespace (``u_<slot>_...``)."""
        return {}

    def textures(self, scene: SceneView) -> dict[str, np.ndarray]:
        """Sampler uniform name (``t_<slot>_...``) -> a float32 array (rows, columns[,
        channels]) its GLSL reads with ``texelFetch`` (row = texel y, column = texel x);
        none by default. The renderer uploads each array once (keyed by the array
        object) and binds it."""
        return {}

    def warnings(self, scene: SceneView) -> tuple[str, ...]:
        """Lines about accepted values that will probably not give what was meant (each
        names the field); none by default. Printed by every front end, never fatal."""
        return ()

    def shades_from_emitter_map(self, scene: SceneView) -> bool:
        """True when, as far as this component goes, a pixel's value is the emitter's
        radiance where its one mirror ray lands: the metric may then shade every phase
        from the emitter map instead of rendering images (a lens, a lobe, Fresnel or a
        sensor say no)."""
        return True

    def keeps_emitter_scale(self, scene: SceneView) -> bool:
        """True when this component leaves the pattern's peak at the emitter's radiance,
        so the metric's threshold is a fraction of the emitter peak; False when it scales
        or mixes the radiance (Fresnel, a microfacet lobe, eq. (1)), and the threshold is
        then taken between the defect-free image's dark and bright levels."""
        return True

    def work_factor(self, scene: SceneView) -> int:
        """Rays this component traces per pixel sample (the work budget counts them)."""
        return 1

    def loop_iterations(self, scene: SceneView, solver: Any) -> int:
        """The most loop iterations this component's GLSL runs for one camera ray (a
        march, a root polish, a lobe's samples), a loop of at most ``n`` iterations
        counting ``n + 1`` (llvmpipe counts the test that ends it); loops of a small constant
        count, which the compiler unrolls, count 0. A driver may stop a fragment's loops
        after a fixed number of iterations in all (llvmpipe: 65535), so the renderer splits
        a pixel's rays over draws that each stay well under it. ``solver``: the renderer's
        dent solver (``march_steps``, ``newton_iterations``)."""
        return 0

    def pattern_loop_iterations(self, scene: SceneView, solver: Any) -> int:
        """The most loop iterations its GLSL runs for one camera ray and each pattern the
        program shades (a reflection model's loop over the patterns, an emitter's series per
        pattern), counted as :meth:`loop_iterations` counts; a frame stack shades up to 64
        patterns from each ray."""
        return 0

    def develop(self, scene: SceneView, image: np.ndarray, exposure: int = 0) -> np.ndarray:
        """What the sensor makes of a rendered radiance image (float32, in place or new);
        the identity but for the sensor. ``exposure`` numbers independent exposures of
        the same scene (their noise differs). The renderer gives ``scene`` with
        ``camera.exposure`` worked out to a number where it was ``"auto"``."""
        return image

    def records(self, scene: SceneView) -> bool:
        """True when :meth:`develop` turns radiance into recorded values (full scale 1),
        which ``camera.exposure`` scales; False but for an active sensor."""
        return False

    def dimming(self, scene: SceneView) -> str | None:
        """What this component takes from the stripes' brightness or contrast, in a few
        words (a lens's defocus, a lobe, a reflectance below 1), or None: the causes a
        low-contrast or underexposed measurement names."""
        return None

    def accuracy_knob(self) -> AccuracyKnob | None:
        """Its accuracy knob (the setting that trades its error for run time, measured by
        ``glshade accuracy``), if it has one: :mod:`glshade.components.accuracy`."""
        return None

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
class RenderComponent(Component):
    """How a frame is computed (precision, rays per pixel): the program's preamble."""

    slot = "render"

    def shades_from_emitter_map(self, scene: SceneView) -> bool:
        return scene.render.supersample == 1


class CameraComponent(Component):
    """How pixels become rays. Oracle: ``pixel_rays`` (one chief ray per pixel sample)
    and ``sample_rays`` (every ray the shader traces, each with its own origin)."""

    slot = "camera"

    def pixel_rays(
        self, scene: SceneView, rows: Any, cols: Any, supersample: int
    ) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def samples(self, scene: SceneView) -> int:
        """Rays per pixel sample (a lens's aperture samples); 1 for a pinhole."""
        return 1

    def work_factor(self, scene: SceneView) -> int:
        return self.samples(scene)

    def sample_rays(
        self, scene: SceneView, rows: Any, cols: Any, supersample: int
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(origins, directions)``, (h, w, S, 3) each: every ray of each pixel."""
        origin, d = self.pixel_rays(scene, rows, cols, supersample)
        h, w = d.shape[:2]
        d = d.reshape(h, w, supersample * supersample, 3)
        return np.broadcast_to(origin, d.shape), d


class SurfaceComponent(Component):
    """A base surface ``y = f(x, z)``. Oracle, all lengths mm, arrays float64:"""

    slot = "surface"

    def domain(
        self, scene: SceneView, o: np.ndarray, d: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """``[t_in, t_out]`` where rays ``o + t d`` ((N, 3) each) are over the domain;
        ``±inf`` when unbounded, NaN when empty."""
        n = len(d)
        return np.full(n, -np.inf), np.full(n, np.inf)

    def band_roots(
        self, scene: SceneView, o: np.ndarray, d: np.ndarray, shift: float
    ) -> list[np.ndarray]:
        """Ray parameters where ``y - f = shift`` (every root; spurious ones only add
        breakpoints to the search)."""
        raise NotImplementedError

    def height(self, scene: SceneView, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        """``f(x, z)``, clipped to the domain's edge outside it."""
        raise NotImplementedError

    def outside(self, scene: SceneView, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        """True where the surface does not exist (its height is NaN)."""
        return np.zeros(np.broadcast(x, z).shape, dtype=bool)

    def normal(
        self, scene: SceneView, x: np.ndarray, z: np.ndarray, dx: np.ndarray, dz: np.ndarray
    ) -> np.ndarray:
        """Unnormalised normal (…, 3) of ``f + D`` given the defect's gradient
        ``(D_x, D_z)``; finite wherever the surface exists."""
        raise NotImplementedError

    def measured(self, scene: SceneView, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        """False where the surface occludes but has no data to reflect from (a height
        map's unmeasured samples): a first hit there is a miss. Everywhere True by default;
        a surface that says False somewhere sets the template variable ``surface_holes``
        and defines ``base_measured`` in its GLSL to match."""
        return np.ones(np.broadcast(x, z).shape, dtype=bool)

    def coverage(self, scene: SceneView) -> Any:
        """How the surface's measured data cover the scene's dent, or None when the
        surface is not measured data (analytic surfaces: the default). A height map
        returns its ``MapCoverage`` (unmeasured share, holes near the dent, the dent at
        the map's edge), so callers never ask which surface it is."""
        return None

    def second_derivatives(self, scene: SceneView) -> tuple[float, float]:
        """``(f_zz, f_xx)`` at the gaze point (1/mm): along the plane of incidence and
        across it; convex is negative (:func:`glshade.metrics.physics.base_curvatures`)."""
        return 0.0, 0.0

    def describe(self, scene: SceneView) -> str:
        """The surface in a few words, for figure titles."""
        return self.name


class DefectComponent(Component):
    """A defect ``D(x, z)`` added to the base surface. Oracle:"""

    slot = "defect"

    def present(self, scene: SceneView) -> bool:
        return True

    def band(self, scene: SceneView) -> tuple[float, float]:
        """``(lo, hi)``: ``D`` lies between them everywhere (mm)."""
        raise NotImplementedError

    def depth(self, scene: SceneView, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        """``D(x, z)`` (mm)."""
        raise NotImplementedError

    def gradient(
        self, scene: SceneView, x: np.ndarray, z: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """``(D_x, D_z)``."""
        raise NotImplementedError

    def breakpoints(self, scene: SceneView, o: np.ndarray, d: np.ndarray) -> list[np.ndarray]:
        """Ray parameters where the defect changes character (the search samples each
        stretch between breakpoints densely)."""
        return []

    def centre(self, scene: SceneView) -> np.ndarray:
        """The defect's centre ``(x0, 0, z0)`` (world mm): the origin of the local frame."""
        return np.zeros(3)


class EmitterComponent(Component):
    """The light source. Oracle: ``coordinates`` (where reflected rays land) and
    ``radiance`` (what they see there); ``pattern`` is what the visibility metric and
    the reflection models' oracles ask for radiance, binarisation level and scale."""

    slot = "emitter"
    #: The instrument that measures what this emitter shows: ``paper`` (the stripes'
    #: binarised edges) or ``pmd`` (a fringe sequence decoded; the emitter then describes
    #: its frames, :meth:`sequence`).
    measured_by: ClassVar[str] = "paper"
    #: What one period of its pattern is called, in words ("stripe", "fringe").
    pattern_noun: ClassVar[str] = "stripe"

    def features(self, scene: SceneView) -> dict[str, Hashable]:
        """``cover_glass``: whether ``lib/emitter_plane.glsl`` refracts through a cover
        glass (:meth:`cover_glass`; none by default), and ``screen_sag``: whether the
        screen sags (``emitter.sag``), the template variables the shared plane needs."""
        from glshade.components.emitter.plane import sag_of

        return {
            "cover_glass": self.cover_glass(scene) is not None,
            "screen_sag": sag_of(scene) is not None,
        }

    def coordinates(
        self, scene: SceneView, points: np.ndarray, directions: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        raise NotImplementedError

    def radiance(self, scene: SceneView, v: np.ndarray) -> np.ndarray:
        """The radiance (float64) where rays land at screen coordinate ``v`` (mm)."""
        return self.pattern(scene).radiance(v)

    def radiance_uv(self, scene: SceneView, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The radiance (float64) where rays land at screen points ``(u, v)`` (mm): the
        float64 oracle of the GLSL ``emitter_radiance``."""
        return self.radiance(scene, self.along(scene, u, v))

    def diffuse(self, scene: SceneView, p: np.ndarray, n: np.ndarray) -> np.ndarray:
        """The Lambertian radiance of the emitter's pattern at hits ``p`` (N, 3) with unit
        normals ``n`` (float64; the oracle of ``emitter_diffuse``): by default the pattern's
        mean radiance times the emitter's form factor (a pattern much finer than the diffuse
        kernel, which spans hundreds of mm of the emitter, averages out)."""
        from glshade.components.emitter.plane import form_factor

        return form_factor(scene, p, n) * self.pattern(scene).mean_radiance()

    def jacobian(
        self, scene: SceneView, points: np.ndarray, r: np.ndarray, a1: np.ndarray, a2: np.ndarray
    ) -> np.ndarray:
        """How the landing point ``(u, v)`` of rays ``points + t r`` (unit ``r``) moves as
        they turn towards ``a1`` and ``a2``: (N, 2, 2), mm per radian (the float64 oracle of
        the GLSL ``emitter_jacobian``)."""
        raise NotImplementedError

    def cover_glass(self, scene: SceneView) -> tuple[float, float] | None:
        """A cover glass in front of the emitting layer, ``(thickness mm, refractive
        index)``, or None (the default): rays refract through it to the layer."""
        return None

    def feature_mm(self, scene: SceneView) -> float:
        """The finest length over which the radiance changes (mm): what a quadrature over
        the emitter must resolve."""
        return float(self.pattern(scene).feature_mm)

    def along(self, scene: SceneView, u: np.ndarray, v: np.ndarray) -> np.ndarray:
        """The screen coordinate :meth:`radiance` takes (mm): ``v``, along which the
        stripes vary (an emitter varying along ``u`` says so)."""
        return v

    def pattern_axes(self, scene: SceneView) -> tuple[int, ...]:
        """The screen coordinates its pattern varies along (0: ``u``, 1: ``v``): ``v`` for
        the stripes."""
        return (1,)

    def finest_period_mm(self, scene: SceneView) -> float:
        """The shortest period of the pattern shown (mm), for the warnings about blur."""
        return float(self.pattern(scene).period_mm)

    def radiance_step(self, scene: SceneView) -> float:
        """The largest step between neighbouring radiance levels the emitter shows (0: a
        continuous radiance): where float32 and float64 may differ by one level."""
        return 0.0

    def sequence(self, scene: SceneView) -> tuple[Any, ...]:
        """The frames of the sequence this emitter shows, in order, for the ``frames``
        output (a stack rendered in one trace). An emitter that shows one pattern has no
        sequence: a one-line error says which emitter does."""
        from glshade.errors import GlshadeError

        raise GlshadeError(no_sequence(self.name))

    def white(self, scene: SceneView) -> Any:
        """The frame of the screen's uniform full scale (each pixel's response to it)."""
        return self.sequence(scene)[0]

    def showing(self, scene: SceneView, frame: Any) -> Any:
        """The scene with its emitter showing ``frame`` of :meth:`sequence` alone."""
        return scene

    def exposure_scene(self, scene: SceneView) -> Any:
        """The scene whose brightest pixel ``camera.exposure = "auto"`` exposes for (its
        defect is removed by the caller): the pattern at phase 0 by default."""
        return scene.with_phase(0.0)  # type: ignore[attr-defined]

    def pattern(self, scene: SceneView) -> Any:
        """The pattern shown: ``period_mm``, ``phase_mm``, ``feature_mm`` (the finest
        length over which it changes), ``radiance(v, phase_mm=None)``,
        ``binary_half_width(threshold)``, ``mean_radiance()`` (see
        :class:`glshade.metrics.visibility.Pattern`)."""
        raise NotImplementedError


def no_sequence(emitter: str) -> str:
    """Why an emitter that shows one pattern has no frame sequence."""
    return (
        f'emitter.kind = "{emitter}" shows one pattern, not a sequence of frames; '
        'phase-measuring deflectometry needs emitter.kind = "fringes"'
    )


class ReflectionComponent(Component):
    """How the surface reflects. Oracle: ``shade``, the pixel value of hits ``p`` seen
    along unit ``d`` with unit normals ``n`` whose mirror rays land at screen points ``uv``
    ((N, 2) mm; ``ok``: on the emitter)."""

    slot = "reflection"
    #: The pixel is the emitter's radiance at the mirror ray's ``v``: a picture can be
    #: shaded from the emitter map alone (the metric's fast path, the viewer's re-shading).
    mirror_only: ClassVar[bool] = False

    def shades_from_emitter_map(self, scene: SceneView) -> bool:
        return self.mirror_only

    def shade(
        self,
        scene: SceneView,
        p: np.ndarray,
        d: np.ndarray,
        n: np.ndarray,
        uv: np.ndarray,
        ok: np.ndarray,
    ) -> np.ndarray:
        raise NotImplementedError

    def footprint(
        self, scene: SceneView, p: np.ndarray, d: np.ndarray, n: np.ndarray
    ) -> tuple[np.ndarray, str] | None:
        """The lobe mapped onto the emitter, linearised about the mirror ray, at hits ``p``
        (N, 3) seen along unit ``d`` with unit normals ``n``: ``(F, kernel)``, ``F`` (N, 2, 2)
        the footprint matrix (mm; a lobe offset ``x`` of the unit ``kernel``,
        ``shaders/lib/kernels.glsl``, lands ``F x`` from the mirror ray's point); None for a
        model without a lobe. The float64 oracle of the footprint its GLSL hands
        ``emitter_filtered``, and what the closed form of the modulation a finish leaves of
        a fringe is computed from (the oracle's ``lobe_footprint``)."""
        return None

    def finish_name(self, scene: SceneView) -> str:
        """The finish in a few words (its model and roughness), for a status that names
        it."""
        return self.name

    def lobe_std_rad(self, scene: SceneView) -> float | None:
        """The angular standard deviation of the reflected direction (rad), or None for
        a perfect mirror. A lobe wider than the stripes can resolve is warned about
        (:func:`glshade.oracle.advice.scene_warnings`)."""
        return None

    def sharpen_hint(self, scene: SceneView, ratio: float) -> str:
        """What would narrow the lobe ``ratio`` times (for the lobe warning)."""
        return f"a lobe {ratio:.3g} times narrower"

    def dimming(self, scene: SceneView) -> str | None:
        std = self.lobe_std_rad(scene)
        if std is None:
            return None
        return f"the {self.name} lobe (angular spread {std * 1e3:.3g} mrad)"


class FresnelComponent(Component):
    """How much the surface reflects by the angle of incidence. Oracle: ``reflectance``."""

    slot = "fresnel"

    def reflectance(self, scene: SceneView, cos_i: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def dimming(self, scene: SceneView) -> str | None:
        """The reflectance at the gaze point (incidence ``90° - θ``), where below 1."""
        cos_i = np.array([np.sin(scene.gaze.theta_rad)])
        share = float(np.asarray(self.reflectance(scene, cos_i)).reshape(-1)[0])
        if share >= 0.999:
            return None
        return f"Fresnel: the surface reflects {share:.1%} at θ {scene.camera.theta_deg:g}°"


class SensorComponent(Component):
    """What the camera's sensor makes of the radiance: :meth:`develop` in NumPy (the
    reference), and where it offers one, the GPU's record pass over a frame stack
    (:mod:`glshade.gpu.sequence`): its GLSL, uniforms and per-frame random keys."""

    slot = "sensor"

    def record_glsl(self, scene: SceneView) -> tuple[str, ...]:
        """Its GLSL for the GPU's record pass, defining ``float sensor_record(float
        radiance, inout RandomStream stream)`` (``lib/philox.glsl``, ``lib/poisson.glsl``
        come before it); empty where it records in NumPy only (the default) or does not
        record."""
        return ()

    def record_uniforms(self, scene: SceneView, gain: float) -> dict[str, object]:
        """The uniforms of :meth:`record_glsl` at the exposure ``gain`` (float64 values,
        ``u_sensor_*``)."""
        return {}

    def frame_keys(self, scene: SceneView, frames: Sequence[Any], recording: int) -> np.ndarray:
        """Each frame's 64-bit random key (``(len(frames), 2)`` uint32) of the
        ``recording``-th recording of ``scene`` showing ``frames``: from the seed, the
        scene and the frame, so two frames, two scenes or two recordings never share a
        noise pattern."""
        return np.zeros((len(frames), 2), np.uint32)


class PartComponent(Component):
    """Where the part stands in the world (NumPy only: the scene reads its table's
    placement)."""

    slot = "part"


# ------------------------------------------------------------------ a scene's components
@dataclass(frozen=True)
class Active:
    """The components filling a scene's slots, in composition order (a scene resolves
    them once: ``scene.active``); ``active.surface`` is the surface component. The
    questions every front end asks of all of them are answered here."""

    components: tuple[Component, ...]

    def __getattr__(self, slot: str) -> Any:
        for component in self.components:
            if component.slot == slot:
                return component
        raise AttributeError(f"no active component in slot {slot!r}")

    def __iter__(self) -> Iterator[Component]:
        return iter(self.components)

    def features(self, scene: SceneView) -> dict[str, Hashable]:
        """Every component's template variables (a name set twice is an error)."""
        variables: dict[str, Hashable] = {}
        for component in self.components:
            for name, value in component.features(scene).items():
                if variables.setdefault(name, value) != value:
                    raise ValueError(f"template variable {name!r} set twice ({component!r})")
        return variables

    def shades_from_emitter_map(self, scene: SceneView) -> bool:
        """The picture is a function of the emitter map: every component says so (a
        mirror, one ray per pixel through a pinhole, no Fresnel, no sensor)."""
        return all(c.shades_from_emitter_map(scene) for c in self.components)

    def keeps_emitter_scale(self, scene: SceneView) -> bool:
        return all(c.keeps_emitter_scale(scene) for c in self.components)

    def work_factor(self, scene: SceneView) -> int:
        """Rays per pixel sample, all components together."""
        factor = 1
        for component in self.components:
            factor *= component.work_factor(scene)
        return factor

    def loop_iterations(self, scene: SceneView, solver: Any, patterns: int = 1) -> int:
        """Loop iterations of one camera ray shading ``patterns`` patterns (the image: 1; a
        frame stack: the frames of a draw), all components together, the sample loop's own
        included."""
        return 1 + sum(
            c.loop_iterations(scene, solver) + patterns * c.pattern_loop_iterations(scene, solver)
            for c in self.components
        )

    def textures(self, scene: SceneView) -> dict[str, np.ndarray]:
        textures: dict[str, np.ndarray] = {}
        for component in self.components:
            textures.update(component.textures(scene))
        return textures

    def develop(self, scene: SceneView, image: np.ndarray, exposure: int = 0) -> np.ndarray:
        for component in self.components:
            image = component.develop(scene, image, exposure)
        return image

    def records(self, scene: SceneView) -> bool:
        """True when a component records the radiance (a sensor): the rendered image is
        then in recorded units, ``camera.exposure`` applied."""
        return any(component.records(scene) for component in self.components)

    def dimming(self, scene: SceneView) -> tuple[str, ...]:
        """What dims the stripes or takes their contrast, one phrase per component."""
        found = (component.dimming(scene) for component in self.components)
        return tuple(phrase for phrase in found if phrase)
