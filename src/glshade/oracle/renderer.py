"""A renderer without OpenGL: the :class:`~glshade.rendering.Renderer` protocol, which the
GL renderer (:class:`glshade.gpu.renderer.Renderer`) satisfies too, on the NumPy float64
oracle (:func:`glshade.oracle.tracer.trace`).

Where no OpenGL context can be made at all, :class:`OracleRenderer` takes the GL renderer's
place: the measuring floor measures one scene, or a PMD station's, on it unchanged (that
floor hands this one its scenes, never the other way round), and its numbers are the GL
renderer's within the fp32 error budget (``tests/test_oracle_renderer.py``). It returns
what the GL renderer returns, in the same types: float32 ``image``, ``distance``,
``rays`` and ``frames``, ``uv`` float32 for an fp32 scene and float64 for an fp64 one (the
oracle computes in float64 either way and rounds only its outputs), bool ``mask``; a sensor
records the image as it does after a GL render.

It is slow: about 40-70 µs per ray on one core (0.7-1.2 s per 128² frame of the paper's
scenes, a ray per pixel), so frames above :data:`DEFAULT_MAX_PIXELS` pixels are refused
unless ``max_pixels`` allows them. A few scenes' traced rays are kept (within a quarter
of the memory budget): a scene that differs from one traced before only by the stripes'
phase, the sensor or the exposure (the metric's phase sweep, a sensor's second exposure)
is shaded again, not traced again. ``iterations`` (the GL dent solve's count) has no
oracle counterpart and is refused.
"""

from __future__ import annotations

import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from glshade.budget import memory_budget_from_env
from glshade.errors import GlshadeError
from glshade.frame import Frame, Outputs, auto_exposure_gain, normalize_outputs
from glshade.oracle.tracer import Rays, trace, trace_rays
from glshade.scene import Scene
from glshade.version import __version__

#: The most pixels a frame may have unless ``max_pixels`` says otherwise: 512² (a ray per
#: pixel: about 15 s on one core).
DEFAULT_MAX_PIXELS = 512 * 512
#: Bytes the tracer holds per traced ray (its origin and direction, distance, emitter point
#: and flags, kept; the camera's arrays and the outputs' copies while it traces) and per ray
#: and shaded pattern (a value and its mean), about.
_BYTES_PER_RAY, _BYTES_PER_RAY_AND_PATTERN = 200, 16
#: Bytes of the tracer's working arrays for one chunk of rays, whatever the frame, about.
_CHUNK_BYTES = 256 << 20
#: The outputs the oracle computes.
ORACLE_OUTPUTS = ("image", "uv", "mask", "distance", "rays", "frames")
#: Scenes whose traced rays are kept, at most (the metric alternates two).
_MAX_TRACES = 4


@dataclass(frozen=True)
class OracleInfo:
    """What the renderer is (``GLContext.info()``'s counterpart): ``renderer`` names it,
    ``version`` is glshade's; the oracle computes in float64 (``fp64``)."""

    renderer: str
    version: str
    fp64: bool = True


def oracle_frame_bytes(scene: Scene, outputs: Iterable[str], frame_count: int = 0) -> int:
    """Bytes, about, the oracle holds to trace one frame of ``outputs`` of ``scene``
    (``frame_count``: emitter frames of the ``frames`` output): every ray's arrays, each
    shaded pattern's value per ray, the float64 and output arrays, a chunk's work."""
    wanted = normalize_outputs(tuple(outputs))
    pixels = scene.camera.width * scene.camera.height
    rays = pixels * scene.render.supersample**2 * scene.active.camera.samples(scene)
    patterns = ("image" in wanted) + frame_count
    per_pixel = 8 * (2 + 2 + 2 + 2) + 12 * patterns  # float64 + float32 outputs
    return (
        rays * (_BYTES_PER_RAY + _BYTES_PER_RAY_AND_PATTERN * patterns)
        + pixels * per_pixel
        + _CHUNK_BYTES
    )


class OracleRenderer:
    """Turns scenes into frames with the NumPy float64 oracle; a context manager.

    ``memory_budget_bytes``: largest frame accepted (default ``GLSHADE_MEMORY_BUDGET_MB``
    or 2 GiB, as the GL renderer's); ``max_pixels``: most pixels per frame (default
    :data:`DEFAULT_MAX_PIXELS`). It holds no resources: :meth:`release` only forgets the
    exposures and traced rays it keeps.
    """

    def __init__(
        self, *, memory_budget_bytes: int | None = None, max_pixels: int = DEFAULT_MAX_PIXELS
    ) -> None:
        if max_pixels < 1:
            raise GlshadeError(f"max_pixels: must be at least 1, got {max_pixels}")
        self.memory_budget_bytes = (
            memory_budget_from_env() if memory_budget_bytes is None else memory_budget_bytes
        )
        self.max_pixels = max_pixels
        self._gains: dict[str, float] = {}  # "auto" exposures, by defect-free scene
        self._traces: dict[str, Rays] = {}  # traced rays, by geometry, the latest last

    @property
    def renderer_string(self) -> str:
        """What renders, in words (the GL renderer's ``GL_RENDERER`` counterpart)."""
        return f"NumPy float64 oracle (glshade {__version__})"

    def info(self) -> OracleInfo:
        return OracleInfo(self.renderer_string, __version__)

    # ---------------------------------------------------------------- lifetime
    def release(self) -> None:
        self._gains.clear()
        self._traces.clear()

    def __enter__(self) -> OracleRenderer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()

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
    ) -> Frame:
        """Render ``scene`` as :meth:`Renderer.render <glshade.gpu.renderer.Renderer.render>`
        does: ``outputs`` a subset of :data:`ORACLE_OUTPUTS`; ``out``: a frame whose
        arrays (of the types returned) are filled in place; with a sensor the image is what
        it records (``exposure``: which of several independent exposures, ``camera.exposure
        = "auto"`` from :meth:`exposure_gain`) unless ``develop`` is False. ``frames``
        (with the ``frames`` output): the emitter frames to shade, every ray traced once
        and shaded for each; the stack is radiance, never developed."""
        wanted = normalize_outputs(outputs)
        stack = tuple(frames or ())
        if ("frames" in wanted) != bool(stack):
            raise GlshadeError(
                "render: the frames output and a non-empty list of frames go together"
            )
        if "iterations" in wanted:
            raise GlshadeError(
                "outputs: iterations counts the GL renderer's dent solve; the NumPy oracle "
                f"computes {', '.join(ORACLE_OUTPUTS)}"
            )
        need = self._check_size(scene, wanted, len(stack))
        rays = self._rays(scene, need)
        traced = trace(scene, tuple(wanted), frames=stack, develop=False, rays=rays)
        image = traced.image
        if image is not None and develop and scene.active.records(scene):
            exposed = scene.with_value("camera.exposure", self.exposure_gain(scene))
            image = scene.active.develop(exposed, image, exposure)
        uv_type = np.float64 if scene.render.precision == "fp64" else np.float32
        arrays = {
            "image": (image, np.float32),
            "uv": (traced.uv, uv_type),
            "mask": (traced.mask, np.bool_),
            "distance": (traced.distance, np.float32),
            "rays": (traced.rays, np.float32),
            "frames": (traced.frames, np.float32),
        }
        return Frame(
            **{
                name: _output(name, array, dtype, out)
                for name, (array, dtype) in arrays.items()
                if array is not None
            }
        )

    def _check_size(self, scene: Scene, wanted: frozenset[str], frame_count: int) -> int:
        """Refuse, in one line and before any work, a frame of more than ``max_pixels``
        pixels or one whose arrays would exceed the memory budget; the bytes it needs."""
        cam = scene.camera
        if cam.width * cam.height > self.max_pixels:
            raise GlshadeError(
                f"camera.width x camera.height: {cam.width}x{cam.height} pixels, more than the "
                f"NumPy oracle renders ({self.max_pixels} pixels: about 50 µs a ray on one "
                "core); use a smaller --size or OracleRenderer(max_pixels=...)"
            )
        need = oracle_frame_bytes(scene, wanted, frame_count)
        if need > self.memory_budget_bytes:
            raise GlshadeError(
                f"camera.width x camera.height: {cam.width}x{cam.height} pixels x "
                f"{scene.render.supersample**2 * scene.active.camera.samples(scene)} rays need "
                f"about {need / (1 << 20):.0f} MiB in the NumPy oracle, more than the memory "
                f"budget of {self.memory_budget_bytes / (1 << 20):.0f} MiB "
                "(GLSHADE_MEMORY_BUDGET_MB)"
            )
        return need

    def _rays(self, scene: Scene, need: int) -> Rays:
        """``scene``'s traced rays: kept from a scene of the same geometry, or traced (the
        kept ones dropped first where they and ``need`` bytes would exceed the budget) and
        kept while all kept stay within a quarter of the memory budget."""
        key = geometry_key(scene)
        rays = self._traces.pop(key, None)
        if rays is None:
            if need + sum(kept.nbytes for kept in self._traces.values()) > self.memory_budget_bytes:
                self._traces.clear()
            rays = trace_rays(scene)
        room = self.memory_budget_bytes // 4
        if rays.nbytes <= room:
            while self._traces and (
                len(self._traces) >= _MAX_TRACES
                or rays.nbytes + sum(kept.nbytes for kept in self._traces.values()) > room
            ):
                self._traces.pop(next(iter(self._traces)))
            self._traces[key] = rays
        return rays

    def exposure_gain(self, scene: Scene) -> float:
        """``camera.exposure`` as a number (:func:`glshade.frame.auto_exposure_gain`; for
        ``"auto"`` the defect-free scene traced once per geometry), as the GL renderer's."""

        def radiance_of(normal: Scene) -> np.ndarray:
            rays = self._rays(normal, self._check_size(normal, frozenset({"image"}), 0))
            return trace(normal, ("image",), develop=False, rays=rays).output("image")

        return auto_exposure_gain(scene, self._gains, radiance_of)


def geometry_key(scene: Scene) -> str:
    """What a scene's traced rays depend on, as text: the scene but for the stripes'
    phase, the sensor, the exposure and the precision (which change only how the rays are
    shaded, recorded or returned)."""
    described = scene.to_dict()
    described.pop("sensor", None)
    for table, key in (("emitter", "phase"), ("camera", "exposure"), ("render", "precision")):
        described[table] = {k: v for k, v in described.get(table, {}).items() if k != key}
    return json.dumps(described, sort_keys=True, default=str)


def _output(name: str, array: np.ndarray, dtype: Any, out: Frame | None) -> np.ndarray:
    """``array`` as the GL renderer returns output ``name`` (``dtype``), written into
    ``out``'s array of that name where one is given (C-contiguous, of that type and
    shape)."""
    given = getattr(out, name) if out is not None else None
    if given is None:
        return np.ascontiguousarray(array, dtype=dtype)
    if given.shape != array.shape or given.dtype != dtype or not given.flags.c_contiguous:
        raise GlshadeError(
            f"out.{name}: must be a C-contiguous {np.dtype(dtype).name} array of shape "
            f"{array.shape}"
        )
    given[...] = array
    return given


__all__ = [
    "DEFAULT_MAX_PIXELS",
    "ORACLE_OUTPUTS",
    "OracleInfo",
    "OracleRenderer",
    "geometry_key",
    "oracle_frame_bytes",
]
