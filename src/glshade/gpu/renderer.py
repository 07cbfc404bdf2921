"""The renderer: scene -> shader features -> program -> frame.

The program is composed from the scene's active components (:mod:`glshade.gpu.compose`:
the template, slot headers and library in ``shaders/``, each component's GLSL in its
folder). One fragment per camera pixel traces the pixel's rays (``render.supersample``²
times a lens's aperture samples), each ray's first hit on the surface (a plane or quadric
in closed form, a formula or a height map marched) carrying the defect, and shades what the
reflection model sees of the emitter's pattern there (the image), or of each emitter frame
of a draw (the ``frames`` output: an image array, at most :data:`MAX_FRAMES_PER_DRAW`
frames a draw; a longer stack is traced again for each further chunk). Only the render
targets a call asks for are attached, drawn and read back into NumPy arrays, and ``rays``
beside them where the program loops over a pixel's samples (each draw's count checks the
driver's loop limit; the frame returns it only where it was asked for). A pixel's rays
whose loops would pass the driver's limit are traced over several draws
(:data:`PASS_LOOP_BUDGET`; a draw the limit cut short again in halves) and added up, in
float64 but for the ``frames`` stack (float32) and ``iterations`` (the most of any draw);
a frame of much work is drawn in bands of rows, so that Ctrl-C is honoured and progress
can be shown; with a sensor, the image is what it records, unless ``develop`` is False.

Numerics (the error budget in fp32; ``render.precision = "fp64"`` runs the same code in
double precision):
- Everything is computed in a frame centred on the dent, ``O = (x0, 0, z0)``: uniforms
  are formed in float64 on the CPU (``C - O`` and friends) and only then rounded.
- Each chief ray is re-originated at its closest approach to the gazing point (a lens ray
  at its own closest approach to the dent), so the solves below work on millimetre-sized
  numbers instead of the camera's 175 mm: rounding the origin shifts the ray sideways by
  ~1e-5 mm, about 3e-4 of a pixel's footprint.
- Quadric base surfaces: sag form ``f = -s r²/(|R| + sqrt(R² - r²))`` and the quadratic
  with ``R²`` cancelled analytically and its roots in the stable ``q, c/q`` pair.
- The dent: bracket between the base surface shifted by ``max(0, -dmax)`` and
  ``min(0, -dmax)``; inside it, from the upper bracket, a march whose steps are bounded by
  the curvature along the ray (it cannot pass the first root), then Newton safeguarded by
  bisection where a step crossed (:class:`RootSolver`).
- The emitter: ``(E - P)·n_E = -De - P·n_E`` and ``(P - E)·e_u = P·e_u``, ``(P - E)·e_v =
  P·e_v``, so no 256 mm quantity is ever subtracted from another.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, cast

import moderngl
import numpy as np

from glshade.budget import memory_budget_from_env
from glshade.budget import number_from_env as _number_from_env
from glshade.components.base import UniformContext
from glshade.errors import ContextError, GlshadeError, SceneError
from glshade.frame import Frame, Outputs, Region, auto_exposure_gain, normalize_outputs
from glshade.gpu.compose import ShaderFeatures, compile_error, component_uniforms, compose
from glshade.gpu.context import GLContext, interrupts_deferred, set_uniform
from glshade.scene import Scene

if TYPE_CHECKING:
    from glshade.gpu.sequence import GpuStack, SequencePasses
    from glshade.progress import Bar

#: Bytes per pixel of each output: GPU render target + host array (fp64 uv: an RGBA32F
#: target of float hi/lo pairs, a float64 host array).
_OUTPUT_BYTES = {
    "image": 2 * 4,
    "uv": 2 * 8,
    "mask": 2 * 1,
    "distance": 2 * 4,
    "iterations": 2 * 4,
    "rays": 2 * 16 + 4,
}
_OUTPUT_BYTES_FP64 = {**_OUTPUT_BYTES, "uv": 16 + 32}
#: Bytes per pixel a frame traced over several draws adds: each output's float64 sum and
#: one draw's float64 copy beside it.
_SUM_BYTES = {"image": 16, "uv": 32, "mask": 0, "distance": 16, "iterations": 4, "rays": 48}
#: Bytes per pixel and emitter frame of the ``frames`` output: the GPU's layer and the host
#: array; traced over several draws, a float32 sum beside them.
_FRAME_BYTES, _FRAME_SUM_BYTES = 2 * 4, 4
#: Most emitter frames one draw shades (one layer each, from the same rays); a longer
#: stack is traced again for each further chunk of frames.
MAX_FRAMES_PER_DRAW = 64


def _attachments(outputs: tuple[str, ...]) -> tuple[str, ...]:
    """The outputs drawn into colour attachments (the ``frames`` output is an image array
    the shader stores into)."""
    return tuple(name for name in outputs if name != "frames")


def _target_format(name: str, precision: str) -> tuple[int, str]:
    """(components, moderngl dtype) of an output's render target."""
    if name == "uv":
        return (4 if precision == "fp64" else 2), "f4"
    if name == "rays":
        return 4, "f4"  # (rays traced whole, reaching the emitter, hitting the surface, 0)
    return 1, ("f1" if name == "mask" else "f4")


#: Most rays one frame may trace (pixels x rays per pixel) unless ``GLSHADE_MAX_RAYS``
#: says otherwise: 4096² pixels at 16 x 16 rays each (87 s on the 2-core llvmpipe).
DEFAULT_MAX_RAYS = 1 << 32
#: A frame of at most this much work (rays, fp64 counted 4 times) is drawn in one call;
#: a larger one in bands of rows, each aimed at :data:`TILE_SECONDS`, so that Ctrl-C is
#: honoured between two bands and progress can be shown.
SINGLE_DRAW_WORK = 1 << 22
TILE_SECONDS = 0.25
#: A frame expected to take longer than this shows a progress bar (when enabled).
PROGRESS_AFTER_SECONDS = 2.0
#: Loop iterations one draw may run per fragment, all loops together (the sample loop,
#: the marches and root polishes, a lobe's samples): llvmpipe stops a fragment's loops
#: after 65535 iterations in all, and a frame whose pixels need more is traced over
#: several draws, each a slice of every pixel's samples (docs/architecture.md).
PASS_LOOP_BUDGET = 16384


@dataclass(frozen=True)
class RootSolver:
    """The dent's root finder (``components/defect/gaussian/hit_dent.glsl``): at most
    ``march_steps`` steps of a march that cannot pass a root (each step is bounded by
    the curvature of the surface along the ray), then, where a step crossed, at most
    ``newton_iterations`` safeguarded Newton steps; both stop when a step is below
    ``tolerance_mm`` (default: 1e-7 mm in fp32, 1e-13 mm in fp64) or below what the
    precision resolves at the hit point."""

    march_steps: int = 48
    newton_iterations: int = 40
    tolerance_mm: float | None = None

    def __post_init__(self) -> None:
        if not 1 <= self.march_steps <= 4096:
            raise SceneError("root solver march_steps", "an integer in [1, 4096]", self.march_steps)
        if not 0 <= self.newton_iterations <= 1000:
            raise SceneError(
                "root solver newton_iterations", "an integer in [0, 1000]", self.newton_iterations
            )
        if self.tolerance_mm is not None and not (
            math.isfinite(self.tolerance_mm) and self.tolerance_mm > 0
        ):
            raise SceneError("root solver tolerance_mm", "a finite number > 0", self.tolerance_mm)

    def tolerance_for(self, precision: str) -> float:
        if self.tolerance_mm is not None:
            return self.tolerance_mm
        return 1e-7 if precision == "fp32" else 1e-13


def max_rays_from_env() -> int:
    """Rays one frame may trace: ``GLSHADE_MAX_RAYS`` or :data:`DEFAULT_MAX_RAYS`."""
    rays = _number_from_env(
        "GLSHADE_MAX_RAYS", "a number of rays >= 1", positive_only=False, lowest=1.0
    )
    return DEFAULT_MAX_RAYS if rays is None else int(rays)


def frame_rays(scene: Scene) -> int:
    """Rays one frame traces: pixels x ``render.supersample``² x what the components
    multiply each by (a lens's aperture samples, a lobe's samples)."""
    rays = scene.camera.width * scene.camera.height * scene.render.supersample**2
    return rays * scene.active.work_factor(scene)


def pixel_samples(scene: Scene) -> int:
    """Camera rays one pixel traces: ``render.supersample``² x the camera's samples (a
    lens's aperture samples)."""
    return scene.render.supersample**2 * scene.active.camera.samples(scene)


def samples_per_draw(
    scene: Scene,
    solver: RootSolver = RootSolver(),
    budget: int = PASS_LOOP_BUDGET,
    frame_count: int = 0,
) -> int:
    """Camera rays of a pixel one draw traces: as many as keep its loop iterations
    (:meth:`Active.loop_iterations <glshade.components.base.Active.loop_iterations>` per
    ray, and with ``frame_count`` emitter frames a loop over them per ray and two per
    pixel) within ``budget``, at least one, at most all."""
    patterns = frame_count or 1
    per_ray = scene.active.loop_iterations(scene, solver, patterns)
    budget = max(1, budget - 2 * (patterns + 1))  # the pixel's loops over its pattern sums
    return max(1, min(pixel_samples(scene), budget // per_ray))


def sampled(features: ShaderFeatures) -> bool:
    """Does the program loop over a pixel's samples (supersampling or a lens)?"""
    variables = dict(features.variables)
    return bool(variables.get("supersample") or variables.get("aperture"))


def drawn_features(scene: Scene, outputs: Outputs, frame_count: int = 0) -> ShaderFeatures:
    """The features a draw of ``outputs`` uses: a program that loops over a pixel's
    samples also counts them (``rays``), which every draw checks."""
    features = ShaderFeatures.from_scene(scene, outputs, frame_count)
    if sampled(features) and "rays" not in features.outputs:
        features = ShaderFeatures.from_scene(scene, (*features.outputs, "rays"), frame_count)
    return features


def check_work_budget(scene: Scene, max_rays: int) -> None:
    """Refuse, before any work, a frame that would trace more than ``max_rays`` rays."""
    rays = frame_rays(scene)
    if rays > max_rays:
        cam, n = scene.camera, scene.render.supersample
        raise GlshadeError(
            f"camera.width x camera.height x render.supersample²: {cam.width}x{cam.height} pixels "
            f"x {n * n} rays "
            f"(x {rays // (cam.width * cam.height * n * n)} aperture and lobe samples) = "
            f"{rays:.3g} rays, more than "
            f"the work budget of {max_rays:.3g} rays per frame (GLSHADE_MAX_RAYS); use a smaller "
            "--size, "
            "--supersample, --aperture-samples or --lobe-samples"
        )


def frame_bytes(
    width: int,
    height: int,
    outputs: Outputs,
    precision: str = "fp32",
    summed: bool = False,
    frame_count: int = 0,
) -> int:
    """Bytes one frame's render targets and host arrays take (``summed``: and the sums of
    a frame traced over several draws; ``frame_count``: emitter frames of the ``frames``
    output)."""
    table = _OUTPUT_BYTES_FP64 if precision == "fp64" else _OUTPUT_BYTES
    names = normalize_outputs(outputs) - {"frames"}
    per_pixel = sum(table[name] for name in names)
    if summed:
        per_pixel += sum(_SUM_BYTES[name] for name in names)
    if "frames" in normalize_outputs(outputs):
        per_pixel += frame_count * (_FRAME_BYTES + (_FRAME_SUM_BYTES if summed else 0))
    return width * height * per_pixel


def check_frame_budget(
    scene: Scene, outputs: Outputs, budget_bytes: int, summed: bool = False, frame_count: int = 0
) -> None:
    """Reject a frame whose buffers would exceed ``budget_bytes``, naming the fields."""
    cam = scene.camera
    need = frame_bytes(cam.width, cam.height, outputs, scene.render.precision, summed, frame_count)
    if need > budget_bytes:
        per_pixel = need // (cam.width * cam.height)
        max_pixels = budget_bytes // per_pixel
        raise SceneError(
            "camera.width x camera.height",
            f"at most {max_pixels} pixels ({math.isqrt(max_pixels)}² square) for outputs "
            f"{', '.join(sorted(normalize_outputs(outputs)))} within the memory budget of "
            f"{budget_bytes / (1 << 20):.0f} MiB (GLSHADE_MEMORY_BUDGET_MB)",
            f"{cam.width} x {cam.height}",
        )


def scene_uniforms(
    scene: Scene,
    solver: RootSolver = RootSolver(),
    features: ShaderFeatures | None = None,
    frames: tuple = (),
) -> dict[str, object]:
    """Every uniform the program for ``scene`` (and ``features``, default: the image)
    declares, computed in float64 by the active components (``frames``: the emitter
    frames of a draw of the ``frames`` output, as the emitter describes them).

    The local frame is the world shifted by the dent centre ``O`` (``Scene.local_origin``).
    The renderer's own: the slice of the samples a draw traces (``u_pass_first``,
    ``u_pass_count``; here all of them), ``u_pass_two`` (2, for the loop-limit check
    behind the ``rays`` output) and ``out_frames`` (the image unit of the frame stack).
    """
    features = features or ShaderFeatures.from_scene(scene)
    context = UniformContext(
        scene.local_origin(), features.template_variables(), solver, tuple(frames)
    )
    values = component_uniforms(scene, features, context)
    if sampled(features):
        values.update(u_pass_first=0, u_pass_count=pixel_samples(scene))
    if "rays" in features.outputs:
        values["u_pass_two"] = 2
    if "frames" in features.outputs:
        values["out_frames"] = 0
    return values


class _Targets:
    """Render targets of one size and output set, reused across frames."""

    def __init__(
        self,
        context: GLContext,
        width: int,
        height: int,
        outputs: tuple[str, ...],
        precision: str,
        frame_count: int = 0,
    ) -> None:
        self.context = context
        self.shape = (height, width)
        with context.current() as ctx:
            self.textures = []
            for name in _attachments(outputs):
                components, dtype = _target_format(name, precision)
                self.textures.append(ctx.texture((width, height), components, dtype=dtype))
            if not self.textures:  # a framebuffer needs an attachment; nothing reads this one
                self.textures.append(ctx.texture((width, height), 1, dtype="f1"))
            self.fbo = ctx.framebuffer(color_attachments=self.textures)
            self.frames = (
                ctx.texture_array((width, height, frame_count), 1, dtype="f4")
                if frame_count
                else None
            )

    def release(self) -> None:
        self.context.park()  # never delete the framebuffer moderngl thinks is bound
        self.fbo.release()
        for texture in self.textures:
            texture.release()
        if self.frames is not None:
            self.frames.release()


class Renderer:
    """Turns scenes into frames on one GL context; a context manager. A
    :class:`glshade.rendering.Renderer`, as the NumPy oracle's renderer is.

    ``context``: an existing :class:`GLContext` to share (not released by this renderer),
    else one is created and owned. ``memory_budget_bytes``: largest frame accepted
    (default ``GLSHADE_MEMORY_BUDGET_MB`` or 2 GiB); ``max_rays``: most rays per frame
    (default ``GLSHADE_MAX_RAYS`` or 2³²). ``root_solver``: the dent solve.
    ``progress``: show a progress bar (stderr) for frames that take over 2 s.
    ``loop_budget``: loop iterations one draw may run per pixel (:data:`PASS_LOOP_BUDGET`):
    a pixel's rays are traced over as many draws as it needs, and summed.

    Large frames are drawn in bands of rows of about a quarter of a second each, so a
    Ctrl-C (KeyboardInterrupt) stops a render within about a second.

    Programs are cached by :class:`ShaderFeatures`; render targets by size and outputs.
    """

    def __init__(
        self,
        context: GLContext | None = None,
        *,
        memory_budget_bytes: int | None = None,
        max_rays: int | None = None,
        root_solver: RootSolver = RootSolver(),
        progress: bool = False,
        loop_budget: int = PASS_LOOP_BUDGET,
    ) -> None:
        self._owns_context = context is None
        self.context = context if context is not None else GLContext()
        self.memory_budget_bytes = (
            memory_budget_from_env() if memory_budget_bytes is None else memory_budget_bytes
        )
        self.max_rays = max_rays_from_env() if max_rays is None else max_rays
        self.progress = progress
        self.root_solver = root_solver
        if loop_budget < 1:
            raise GlshadeError(f"loop_budget: must be at least 1, got {loop_budget}")
        self.loop_budget = loop_budget
        self._programs: dict[ShaderFeatures, tuple[moderngl.Program, moderngl.VertexArray]] = {}
        self._gains: dict[str, float] = {}  # "auto" exposures, by defect-free scene
        self._targets: dict[tuple[int, int, tuple[str, ...], bool, int], _Targets] = {}
        self._uniform_names: dict[ShaderFeatures, tuple[str, ...]] = {}
        self._textures: dict[int, tuple[np.ndarray, moderngl.Texture]] = {}
        self._max_side = self.context.info().max_texture_size
        self._fp64 = self.context.info().fp64
        self._sequence_passes: SequencePasses | None = None

    # ---------------------------------------------------------------- lifetime
    def release(self) -> None:
        if self.context.ctx is not None:
            with self.context.current():
                for program, vao in self._programs.values():
                    vao.release()
                    program.release()
                for targets in self._targets.values():
                    targets.release()
                for _, texture in self._textures.values():
                    texture.release()
        if self._sequence_passes is not None:
            self._sequence_passes.release()
            self._sequence_passes = None
        self._textures.clear()
        self._programs.clear()
        self._uniform_names.clear()
        self._targets.clear()
        if self._owns_context:
            self.context.release()

    def __enter__(self) -> Renderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()

    # ---------------------------------------------------------------- programs
    def program(self, features: ShaderFeatures) -> moderngl.Program:
        """The compiled program for a feature set (compiled once per renderer)."""
        with self.context.current():
            return self._program(features)[0]

    def _program(self, features: ShaderFeatures) -> tuple[moderngl.Program, moderngl.VertexArray]:
        cached = self._programs.get(features)
        if cached is not None:
            return cached
        if features.precision == "fp64" and not self._fp64:
            raise ContextError(
                "render.precision = fp64 needs GL_ARB_gpu_shader_fp64, which this GL lacks"
            )
        vertex, fragment = compose(features)
        with self.context.current() as ctx:
            try:
                with interrupts_deferred():  # a Ctrl-C inside LLVM's compile crashes it
                    program = ctx.program(vertex_shader=vertex, fragment_shader=fragment)
            except moderngl.Error as exc:
                text = str(exc)
                stage, source = (
                    ("vertex", vertex) if "vertex_shader" in text else ("fragment", fragment)
                )
                raise compile_error(stage, text, source, features) from None
            vao = ctx.vertex_array(program, [])
        self._programs[features] = (program, vao)
        return program, vao

    def _active_uniforms(
        self, program: moderngl.Program, features: ShaderFeatures
    ) -> tuple[str, ...]:
        """The uniforms the driver kept in ``program`` (each must be given a value: a
        uniform left unset would silently read 0)."""
        names = self._uniform_names.get(features)
        if names is None:
            names = tuple(name for name in program if isinstance(program[name], moderngl.Uniform))
            self._uniform_names[features] = names
        return names

    def _render_targets(self, width: int, height: int, features: ShaderFeatures) -> _Targets:
        outputs, precision = features.outputs, features.precision
        key = (
            width,
            height,
            outputs,
            precision == "fp64" and "uv" in outputs,
            features.frame_count,
        )
        targets = self._targets.pop(key, None)
        if targets is not None:
            self._targets[key] = targets  # the most recently used, the last released
        else:
            if len(self._targets) >= 4:  # keep a few sizes, release the oldest
                oldest = next(iter(self._targets))
                self._targets.pop(oldest).release()
            targets = _Targets(
                self.context, width, height, outputs, precision, features.frame_count
            )
            self._targets[key] = targets
        return targets

    # ---------------------------------------------------------------- render
    def render(
        self,
        scene: Scene,
        outputs: Outputs = ("image",),
        *,
        out: Frame | None = None,
        exposure: int = 0,
        frames: Sequence[Any] | None = None,
        develop: bool = True,
        region: Region | None = None,
    ) -> Frame:
        """Render ``scene``; ``outputs`` is a subset of :data:`glshade.frame.OUTPUTS`.
        ``region``: only its pixels are traced, and every array has its shape (with a
        sensor, a region's image is developed alone: a noise draw of its own).

        ``out``: a frame whose arrays (float32 image, float32 uv, bool mask of the right
        shape) are filled in place instead of allocating new ones. With a sensor the image
        is what it records (``exposure``: which of several independent exposures), unless
        ``develop`` is False: then it is the radiance that reaches the sensor.

        ``frames`` (with the ``frames`` output): the emitter frames to shade, as the
        emitter describes them (:meth:`~glshade.components.base.EmitterComponent.sequence`);
        every ray is traced once and shaded for each, at most
        :data:`MAX_FRAMES_PER_DRAW` a draw. The stack is radiance, never developed.
        """
        wanted = normalize_outputs(outputs)
        stack = tuple(frames or ())
        if ("frames" in wanted) != bool(stack):
            raise GlshadeError(
                "render: the frames output and a non-empty list of frames go together"
            )
        features, _ = self._checked(scene, outputs, len(stack))
        with self.context.current():
            if stack:
                frame = self._draw_stack(scene, features, out, stack, region)
            else:
                frame = self._draw(scene, features, out, region=region)
        if frame.rays is not None and "rays" not in wanted:
            frame = dataclasses.replace(frame, rays=None)
        if frame.image is not None and develop and scene.active.records(scene):
            exposed = scene.with_value("camera.exposure", self.exposure_gain(scene))
            image = scene.active.develop(exposed, frame.image, exposure)
            if image is not frame.image:
                frame.image[...] = image
        return frame

    def _checked(
        self, scene: Scene, outputs: Outputs, frame_count: int
    ) -> tuple[ShaderFeatures, bool]:
        """The features a render of ``outputs`` (and ``frame_count`` emitter frames)
        draws, and whether its samples are summed over several draws; a frame too large
        for the driver, the memory budget or the work budget is refused first."""
        per_draw = min(frame_count, MAX_FRAMES_PER_DRAW)
        features = drawn_features(scene, outputs, per_draw)
        cam = scene.camera
        if max(cam.width, cam.height) > self._max_side:
            raise SceneError(
                "camera.width/height",
                f"at most {self._max_side} pixels (GL_MAX_TEXTURE_SIZE)",
                max(cam.width, cam.height),
            )
        summed = sampled(features) and (
            samples_per_draw(scene, self.root_solver, self.loop_budget, per_draw)
            < pixel_samples(scene)
        )
        check_frame_budget(scene, features.outputs, self.memory_budget_bytes, summed, per_draw)
        check_work_budget(scene, self.max_rays)
        return features, summed

    # ---------------------------------------------------------------- sequences
    def trace_sequence(
        self, scene: Scene, frames: Sequence[Any], region: Region | None = None
    ) -> tuple[Frame, GpuStack]:
        """The emitter ``frames`` of ``scene`` shaded from one trace and kept on the GPU
        (a :class:`~glshade.gpu.sequence.GpuStack`, the renderer's until its next trace
        of this size), with the ``uv`` map read back; ``region``: only its pixels are
        traced, and the map has its shape. Nothing but the map crosses to the host
        unless the stack's draws are summed on it (a pixel's samples over several
        draws, or more than :data:`MAX_FRAMES_PER_DRAW` frames): then the stack is read,
        summed and sent back."""
        from glshade.gpu.sequence import GpuStack

        stack = tuple(frames)
        if not stack:
            raise GlshadeError("trace_sequence: no frames")
        features, summed = self._checked(scene, ("frames", "uv"), len(stack))
        height, width = scene.camera.height, scene.camera.width
        with self.context.current():
            if len(stack) <= features.frame_count and not summed:
                frame = self._draw(scene, features, None, stack, region, read_frames=False)
                targets = self._render_targets(width, height, features)
                assert targets.frames is not None
                return frame, GpuStack(targets.frames, len(stack), (height, width))
            frame = self._draw_stack(scene, features, None, stack, region)
            held = self.sequence_passes().upload(frame.output("frames"), (height, width), region)
        return dataclasses.replace(frame, frames=None), held

    def sequence_passes(self) -> SequencePasses:
        """The passes over a frame stack on the GPU (recording, decoding), made once."""
        from glshade.gpu.sequence import SequencePasses

        if self._sequence_passes is None:
            self._sequence_passes = SequencePasses(self.context)
        return self._sequence_passes

    def _draw_stack(
        self,
        scene: Scene,
        features: ShaderFeatures,
        out: Frame | None,
        stack: tuple,
        region: Region | None = None,
    ) -> Frame:
        """Every frame of ``stack``, :attr:`ShaderFeatures.frame_count` a draw (the last
        chunk padded with its own last frame); the other outputs come from the first
        (``region``: only its pixels, the arrays its shape)."""
        per_draw = features.frame_count
        rows, cols = _region_shape(scene, region)
        layers = np.empty((len(stack), rows, cols), np.float32)
        first: Frame | None = None
        for start in range(0, len(stack), per_draw):
            chunk = stack[start : start + per_draw]
            padded = chunk + (chunk[-1],) * (per_draw - len(chunk))
            frame = self._draw(scene, features, out if first is None else None, padded, region)
            layers[start : start + len(chunk)] = frame.output("frames")[: len(chunk)]
            first = first or frame
        assert first is not None
        return dataclasses.replace(first, frames=layers)

    def exposure_gain(self, scene: Scene) -> float:
        """``camera.exposure`` as a number (:func:`glshade.frame.auto_exposure_gain`; for
        ``"auto"`` the defect-free scene drawn once per geometry)."""

        def radiance_of(normal: Scene) -> np.ndarray:
            features = drawn_features(normal, ("image",))
            with self.context.current():
                return self._draw(normal, features, None).output("image")

        return auto_exposure_gain(scene, self._gains, radiance_of)

    def _draw(
        self,
        scene: Scene,
        features: ShaderFeatures,
        out: Frame | None,
        frames: tuple = (),
        region: Region | None = None,
        read_frames: bool = True,
    ) -> Frame:
        """One frame of ``features.outputs`` (``frames``: the emitter frames of the
        ``frames`` output, read back unless ``read_frames`` is False; ``region``: only its
        pixels are drawn and read, the arrays its shape); a program that loops over a
        pixel's samples also writes ``rays``, and its samples are traced over as many
        draws as :func:`samples_per_draw` says (:meth:`_draw_sampled`)."""
        width, height = scene.camera.width, scene.camera.height
        program, vao = self._program(features)
        uniforms = scene_uniforms(scene, self.root_solver, features, frames)
        textures = scene.active.textures(scene)
        for unit, (name, array) in enumerate(textures.items()):
            self._texture(array).use(location=unit)
            uniforms[name] = unit
        for name in self._active_uniforms(program, features):
            if name not in uniforms:
                raise GlshadeError(
                    f"uniform {name} of {features.selected()} is provided by no active component"
                )
            set_uniform(program, name, uniforms[name])  # only the uniforms the program kept
        targets = self._render_targets(width, height, features)
        targets.fbo.use()
        targets.fbo.viewport = (0, 0, width, height)
        if targets.frames is not None:
            targets.frames.bind_to_image(0, read=False, write=True)
        area = region or Region(0, 0, height, width)
        work = frame_rays(scene) * (4 if features.precision == "fp64" else 1)
        work = max(1, work * area.rows * area.cols // (width * height))
        if not sampled(features):
            self._draw_once(vao, area, work)
            arrays = self._read(targets, features, area, out, read_frames)
            if "rays" in arrays:
                rays = self._output_array("rays", area.rows, area.cols, features.precision, out)
                rays[...] = arrays["rays"][..., 0]
                arrays["rays"] = rays
            return Frame(**arrays)
        return self._draw_sampled(scene, features, program, vao, targets, work, out, area)

    def _draw_once(self, vao: moderngl.VertexArray, area: Region, work: int) -> None:
        if work <= SINGLE_DRAW_WORK:
            self.context.gl.scissor = area.scissor
            try:
                vao.render(moderngl.TRIANGLES, vertices=3)
                self.context.wait()  # the trace, other Python threads running meanwhile
            finally:
                self.context.gl.scissor = None
        else:
            self._draw_in_bands(vao, area, work)

    def _read(
        self,
        targets: _Targets,
        features: ShaderFeatures,
        area: Region,
        out: Frame | None,
        read_frames: bool = True,
    ) -> dict[str, np.ndarray]:
        """Every render target over ``area``, read back (``out``'s arrays filled where
        given; ``rays`` with its four channels; the frames unless ``read_frames`` is
        False: they stay in the targets' image array)."""
        arrays: dict[str, np.ndarray] = {}
        width, height = area.cols, area.rows
        viewport = area.viewport
        if targets.frames is not None:
            self.context.gl.memory_barrier()
        if targets.frames is not None and read_frames:
            arrays["frames"] = self._read_frames(targets, features.frame_count, area)
        for index, name in enumerate(_attachments(features.outputs)):
            components, dtype = _target_format(name, features.precision)
            if name == "rays":
                array = np.empty((height, width, 4), np.float32)
                targets.fbo.read_into(
                    array, viewport=viewport, components=4, attachment=index, dtype="f4"
                )
                arrays[name] = array
                continue
            array = self._output_array(name, height, width, features.precision, out)
            if name == "uv" and features.precision == "fp64":
                pairs = np.empty((height, width, 4), np.float32)  # (u_hi, v_hi, u_lo, v_lo)
                targets.fbo.read_into(
                    pairs, viewport=viewport, components=4, attachment=index, dtype="f4"
                )
                np.add(pairs[..., :2], pairs[..., 2:], out=array, dtype=np.float64)
            else:
                host = array.view(np.uint8) if name == "mask" else array
                targets.fbo.read_into(
                    host, viewport=viewport, components=components, attachment=index, dtype=dtype
                )
            arrays[name] = array
        return arrays

    def _read_frames(self, targets: _Targets, count: int, area: Region) -> np.ndarray:
        """The frames target's ``count`` layers over ``area``: the whole array read, or
        a smaller area copied on the GPU first where the context can (so that only its
        pixels cross to the host)."""
        from glshade.gpu.sequence import GpuStack, supports_sequence_passes

        assert targets.frames is not None
        if (area.rows, area.cols) != targets.shape and supports_sequence_passes(self.context):
            stack = GpuStack(targets.frames, count, targets.shape)
            return self.sequence_passes().read(stack, area)
        whole = np.empty((count, *targets.shape), np.float32)
        targets.frames.read_into(whole)
        return whole[:, area.rows_slice, area.cols_slice]

    def _draw_sampled(
        self,
        scene: Scene,
        features: ShaderFeatures,
        program: moderngl.Program,
        vao: moderngl.VertexArray,
        targets: _Targets,
        work: int,
        out: Frame | None,
        area: Region,
    ) -> Frame:
        """Trace every pixel's samples ``0 … S-1`` in slices ``[first, first + count)``,
        one draw each, and add the draws up in float64: the image is the sum of their
        shares of the mean, uv and distance the means weighted by each draw's counts,
        iterations the most. Each draw's ``rays`` must equal its count in every pixel: a
        draw a driver's loop limit cut short is traced again in halves."""
        width, height = area.cols, area.rows
        total = pixel_samples(scene)
        size = samples_per_draw(scene, self.root_solver, self.loop_budget, features.frame_count)
        first_uniform = cast(moderngl.Uniform, program["u_pass_first"])
        count_uniform = cast(moderngl.Uniform, program["u_pass_count"])
        sums: dict[str, np.ndarray] = {}
        first = 0
        while first < total:
            count = min(size, total - first)
            first_uniform.value, count_uniform.value = first, count
            self._draw_once(vao, area, max(1, work * count // total))
            whole = count == total
            arrays = self._read(targets, features, area, out if whole else None)
            counts = arrays["rays"]
            if (counts[..., 0] < count).any():
                if count == 1:
                    raise GlshadeError(
                        "one ray of this scene runs more loop iterations than the driver "
                        "allows a pixel (its loop limit); lower the root solver's "
                        "march_steps or render.lobe_samples"
                    )
                size = count // 2
                continue
            if whole:
                rays = self._output_array("rays", height, width, features.precision, out)
                rays[...] = counts[..., 0]
                return Frame(**{**arrays, "rays": rays})
            _accumulate(sums, arrays)
            first += count
        return Frame(**_finish(sums, features, out, self._output_array))

    def _texture(self, array: np.ndarray) -> moderngl.Texture:
        """The texture holding ``array`` (float32; (rows, cols) or (rows, cols, channels)),
        uploaded once per array
        object; a few are kept, the oldest released."""
        cached = self._textures.get(id(array))
        if cached is not None and cached[0] is array:
            return cached[1]
        if len(self._textures) >= 4:
            self._textures.pop(next(iter(self._textures)))[1].release()
        data = np.ascontiguousarray(array, dtype=np.float32)
        rows, cols = data.shape[:2]
        channels = data.shape[2] if data.ndim == 3 else 1
        texture = self.context.gl.texture((cols, rows), channels, data=data.tobytes(), dtype="f4")
        texture.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self._textures[id(array)] = (array, texture)
        return texture

    def _draw_in_bands(self, vao: moderngl.VertexArray, area: Region, work: int) -> None:
        """Draw ``area`` as bands of rows (scissored), waiting for each, so that Python
        sees a KeyboardInterrupt between two of them; each band is sized from the last
        one's time to take about :data:`TILE_SECONDS`."""
        ctx = self.context.gl
        width, height = area.cols, area.rows
        rows = max(1, SINGLE_DRAW_WORK * height // work)
        done, start, bar = 0, time.perf_counter(), None
        try:
            while done < height:
                band = min(rows, height - done)
                begin = time.perf_counter()
                ctx.scissor = (area.col0, area.row0 + done, width, band)
                vao.render(moderngl.TRIANGLES, vertices=3)
                self.context.wait()
                seconds = time.perf_counter() - begin
                done += band
                rows = max(1, min(height, int(band * TILE_SECONDS / max(seconds, 1e-4))))
                elapsed = time.perf_counter() - start
                if (
                    bar is None
                    and self.progress
                    and elapsed * height / done > PROGRESS_AFTER_SECONDS
                ):
                    bar = _progress_bar(height, done)
                elif bar is not None:
                    bar.update(band)
        finally:
            ctx.scissor = None
            if bar is not None:
                bar.close()

    @staticmethod
    def _output_array(
        name: str, height: int, width: int, precision: str, out: Frame | None
    ) -> np.ndarray:
        shape = (height, width, 2) if name == "uv" else (height, width)
        dtype: type[np.generic]
        if name == "mask":
            dtype = np.bool_
        elif name == "uv" and precision == "fp64":
            dtype = np.float64
        else:
            dtype = np.float32
        given = getattr(out, name) if out is not None else None
        if given is None:
            return np.empty(shape, dtype)
        if given.shape != shape or given.dtype != dtype or not given.flags.c_contiguous:
            raise GlshadeError(
                f"out.{name}: must be a C-contiguous {np.dtype(dtype).name} array of shape {shape}"
            )
        return given


def _region_shape(scene: Scene, region: Region | None) -> tuple[int, int]:
    """``(rows, columns)`` a draw over ``region`` (None: the whole image) returns."""
    if region is None:
        return scene.camera.height, scene.camera.width
    return region.rows, region.cols


def _accumulate(sums: dict[str, np.ndarray], arrays: dict[str, np.ndarray]) -> None:
    """Add one draw's outputs to the float64 sums of a frame traced over several draws."""
    counts = arrays["rays"].astype(np.float64)
    hits, surface_hits = counts[..., 1], counts[..., 2]
    parts: dict[str, np.ndarray] = {"rays": counts}
    if "image" in arrays:
        parts["image"] = arrays["image"].astype(np.float64)
    if "frames" in arrays:
        parts["frames"] = arrays["frames"]  # float32 shares of each frame's mean
    if "uv" in arrays:
        uv = arrays["uv"].astype(np.float64)
        parts["uv"] = np.where(hits[..., None] > 0, uv * hits[..., None], 0.0)
    if "distance" in arrays:
        distance = arrays["distance"].astype(np.float64)
        parts["distance"] = np.where(surface_hits > 0, distance * surface_hits, 0.0)
    for name, part in parts.items():
        if name in sums:
            sums[name] += part
        else:
            sums[name] = part
    if "iterations" in arrays:
        most = arrays["iterations"]
        sums["iterations"] = np.maximum(sums["iterations"], most) if "iterations" in sums else most


def _finish(
    sums: dict[str, np.ndarray],
    features: ShaderFeatures,
    out: Frame | None,
    output_array: Callable[[str, int, int, str, Frame | None], np.ndarray],
) -> dict[str, np.ndarray]:
    """The frame's arrays from the sums of its draws (``out``'s filled where given)."""
    counts = sums["rays"]
    hits, surface_hits = counts[..., 1], counts[..., 2]
    height, width = counts.shape[:2]
    arrays: dict[str, np.ndarray] = {}
    for name in features.outputs:
        if name == "frames":
            arrays[name] = sums["frames"]
            continue
        array = output_array(name, height, width, features.precision, out)
        with np.errstate(invalid="ignore", divide="ignore"):
            if name == "image":
                array[...] = sums["image"]
            elif name == "uv":
                array[...] = np.where(hits[..., None] > 0, sums["uv"] / hits[..., None], np.nan)
            elif name == "mask":
                array[...] = hits > 0
            elif name == "distance":
                array[...] = np.where(surface_hits > 0, sums["distance"] / surface_hits, np.nan)
            elif name == "iterations":
                array[...] = sums["iterations"]
            elif name == "rays":
                array[...] = counts[..., 0]
        arrays[name] = array
    return arrays


def _progress_bar(total_rows: int, done_rows: int) -> Bar | None:
    """A slow frame's bar: on a terminal only, and gone when the frame is done
    (:mod:`glshade.progress`)."""
    from glshade.progress import progress_bar

    return progress_bar(total_rows, "glshade render", "row", initial=done_rows, leave=False)


def render(scene: Scene, outputs: Outputs = ("image",)) -> Frame:
    """One-shot convenience: create a context, render, release."""
    with Renderer() as renderer:
        return renderer.render(scene, outputs)
