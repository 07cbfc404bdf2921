"""A frame stack's passes on the GPU: recorded through the sensor and decoded where it was
traced, so that only the decoded maps cross to the host.

A phase-measuring case traces its fringe sequence in one pass (the renderer's ``frames``
output, :meth:`Renderer.trace_sequence <glshade.gpu.renderer.Renderer.trace_sequence>`)
and keeps it on the GPU (:class:`GpuStack`). Two compute passes follow
(``shaders/passes/``):

- **record** (``record.comp.glsl``): each layer as the sensor records it. The sensor's own
  GLSL (its component's :meth:`~glshade.components.base.SensorComponent.record_glsl`)
  draws its noise from a counter-based generator (Philox4x32-10, ``lib/philox.glsl``)
  keyed per frame by the sensor's seed, the scene, the frame and the recording
  (:meth:`~glshade.components.base.SensorComponent.frame_keys`) and counted by the pixel:
  a pixel records the same whether the pass covers the whole image or a region of it,
  in whatever order and tiling the GPU runs it. The NumPy sensor
  (:meth:`~glshade.components.base.Component.develop`) stays the reference.
- **decode** (``decode.comp.glsl``): per coded direction and period the phasor sums (in
  float64), modulation, offset and wrapped phase, the validity and the temporal
  unwrapping down to the second finest period; :func:`finish_decode` finishes on the host
  in float64, with the NumPy decoder's own steps
  (:mod:`glshade.instruments.pmd.decode`'s ``coarsest_coordinate`` and
  ``unwrap_step``, passed in by the caller: this module knows no instrument).

Programs are composed once per feature set (the sensor's files; the coding's periods,
shifts and directions) and cached; a pass over a :class:`~glshade.frame.Region` covers
only its pixels and its maps have the region's shape.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import moderngl
import numpy as np

from glshade.errors import ContextError
from glshade.frame import Region
from glshade.gpu.compose import compile_error, qualified, render_template
from glshade.gpu.context import GLContext, interrupts_deferred, set_uniform

if TYPE_CHECKING:
    from glshade.components.base import Component

#: The compute passes' workgroup: 8 x 8 pixels.
GROUP = 8  # lib/region_pass.glsl's workgroup side
#: GL 4.3 brought compute shaders; the decode pass needs float64 (GL 4.0).
COMPUTE_GL = 430
#: Image arrays kept per role (recorded frames, maps, copies), by size.
KEPT_PER_ROLE = 3


@dataclass(frozen=True)
class GpuStack:
    """Frames held on the GPU: the first ``layers`` layers of ``texture`` (an r32f image
    array of the image's ``shape``, rows and columns). The renderer or pass that made it
    owns it; it is valid until that one makes its next stack of this size."""

    texture: moderngl.TextureArray
    layers: int
    shape: tuple[int, int]


@dataclass(frozen=True)
class DecodePlan:
    """What the decode pass needs of a coding: each coded direction's first frame in the
    stack and the screen's extent along it (mm), the ``periods_mm`` (finest first), the
    phase ``steps_rad`` of the shifts, and the ``threshold`` modulation a valid pixel
    needs (the frames' units)."""

    first_layers: tuple[int, ...]
    extents_mm: tuple[float, ...]
    periods_mm: tuple[float, ...]
    steps_rad: tuple[float, ...]
    threshold: float

    @property
    def layers_per_direction(self) -> int:
        """Maps per direction: the finest sums (2, and 2 for their rest below float32),
        the coarse coordinate, the validity, then per period the modulation, the offset
        and the wrapped phase."""
        return 6 + 3 * len(self.periods_mm)


@dataclass(frozen=True)
class DirectionMaps:
    """One direction's maps from the decode pass (region-shaped, float32 but
    ``valid``): the finest period's phasor sums ``sine`` and ``cosine`` (float64: the
    float64 sum's nearest float plus its rest), ``coarse`` the
    coordinate unwrapped down to the second finest period (mm from the screen's edge;
    NaN for one period), per period ``modulation``, ``offset`` and ``wrapped`` (K, rows,
    cols)."""

    sine: np.ndarray
    cosine: np.ndarray
    coarse: np.ndarray
    valid: np.ndarray
    modulation: np.ndarray
    offset: np.ndarray
    wrapped: np.ndarray


def supports_sequence_passes(context: GLContext) -> bool:
    """Can this context record and decode a stack on the GPU (compute shaders and
    float64)?"""
    info = context.info()
    return info.version_code >= COMPUTE_GL and info.fp64


class SequencePasses:
    """The record and decode passes on one GL context, their programs and buffers made
    once and kept; :meth:`release` lets them go."""

    def __init__(self, context: GLContext) -> None:
        if not supports_sequence_passes(context):
            raise ContextError(
                "recording and decoding on the GPU need compute shaders (GL 4.3) and fp64"
            )
        self.context = context
        self._programs: dict[tuple, moderngl.ComputeShader] = {}
        self._arrays: dict[tuple, moderngl.TextureArray] = {}
        self._keys: moderngl.Buffer | None = None

    def release(self) -> None:
        if self.context.ctx is not None:
            with self.context.current():
                for program in self._programs.values():
                    program.release()
                for array in self._arrays.values():
                    array.release()
                if self._keys is not None:
                    self._keys.release()
        self._programs.clear()
        self._arrays.clear()
        self._keys = None

    # ------------------------------------------------------------------ storage
    def _array(self, role: str, shape: tuple[int, int], layers: int) -> moderngl.TextureArray:
        """An image array for ``role`` of this size, made once: the last
        :data:`KEPT_PER_ROLE` sizes of each role are kept (a baseline's whole image, a
        dent's region and its window alternate)."""
        key = (role, shape, layers)
        array = self._arrays.pop(key, None)
        if array is None:
            same = [k for k in self._arrays if k[0] == role]
            if len(same) >= KEPT_PER_ROLE:
                self._arrays.pop(same[0]).release()  # the least recently used
            rows, cols = shape
            array = self.context.gl.texture_array((cols, rows, layers), 1, dtype="f4")
        self._arrays[key] = array
        return array

    def upload(
        self, layers: np.ndarray, shape: tuple[int, int], region: Region | None = None
    ) -> GpuStack:
        """``layers`` (F, rows, cols: the image, or ``region`` of it) sent to an image
        array of the image's ``shape``."""
        count = len(layers)
        with self.context.current():
            array = self._array("uploaded", shape, count)
            data = np.ascontiguousarray(layers, np.float32)
            area = region or Region(0, 0, *shape)
            array.write(data, viewport=(area.col0, area.row0, 0, area.cols, area.rows, count))
        return GpuStack(array, count, shape)

    def read(
        self, stack: GpuStack, region: Region | None = None, layers: Sequence[int] | None = None
    ) -> np.ndarray:
        """The stack's ``layers`` (default: all) over ``region`` (default: the image), as
        a float32 array (layers, rows, cols): copied on the GPU into an array of their
        size first, so that only they cross to the host."""
        chosen = np.asarray(range(stack.layers) if layers is None else list(layers), np.int32)
        area = region or Region(0, 0, *stack.shape)
        program = self._program(("copy",), "passes/copy.comp.glsl", ())
        with self.context.current() as ctx:
            copy = self._array("copy", (area.rows, area.cols), len(chosen))
            listed = ctx.buffer(chosen.tobytes())
            try:
                listed.bind_to_storage_buffer(1)
                stack.texture.bind_to_image(0, read=True, write=False)
                copy.bind_to_image(1, read=False, write=True)
                set_uniform(program, "u_layers", len(chosen))
                self._run(program, area)
            finally:
                listed.release()
            out = np.empty((len(chosen), area.rows, area.cols), np.float32)
            copy.read_into(out)
        return out

    # ------------------------------------------------------------------ programs
    def _program(
        self, key: tuple, template: str, components: tuple, **variables: object
    ) -> moderngl.ComputeShader:
        program = self._programs.get(key)
        if program is None:
            source = render_template(template, components, **variables)
            with self.context.current() as ctx:
                try:
                    with interrupts_deferred():
                        program = ctx.compute_shader(source)
                except moderngl.Error as exc:
                    raise compile_error("compute", str(exc), source) from None
            self._programs[key] = program
        return program

    def _run(self, program: moderngl.ComputeShader, area: Region) -> None:
        set_uniform(program, "u_origin", (area.col0, area.row0))
        set_uniform(program, "u_size", (area.cols, area.rows))
        program.run(math.ceil(area.cols / GROUP), math.ceil(area.rows / GROUP), 1)
        self.context.gl.memory_barrier()
        self.context.wait()

    # ------------------------------------------------------------------ record
    def record(
        self,
        stack: GpuStack,
        sensor: Component,
        sensor_files: tuple[str, ...],
        uniforms: dict[str, object],
        frame_keys: np.ndarray,
        region: Region | None = None,
    ) -> GpuStack:
        """The stack as the ``sensor`` records it (its GLSL ``sensor_files``, their
        ``uniforms``; ``frame_keys`` (layers, 2) uint32: each layer's random key), over
        ``region`` (default: the image): a second image array of the stack's size, the
        pass's own (the next record of this size writes over it)."""
        keys = np.ascontiguousarray(frame_keys, np.uint32)
        if keys.shape != (stack.layers, 2):
            raise ValueError(f"frame_keys: shape ({stack.layers}, 2) wanted, got {keys.shape}")
        files = tuple(qualified(sensor, name) for name in sensor_files)
        program = self._program(
            ("record", type(sensor), files),
            "passes/record.comp.glsl",
            (sensor,),
            sensor_files=files,
        )
        with self.context.current() as ctx:
            target = self._array("recorded", stack.shape, stack.layers)
            if self._keys is None or self._keys.size < keys.nbytes:
                if self._keys is not None:
                    self._keys.release()
                self._keys = ctx.buffer(reserve=max(keys.nbytes, 1024))
            self._keys.write(keys.tobytes())
            self._keys.bind_to_storage_buffer(0)
            stack.texture.bind_to_image(0, read=True, write=False)
            target.bind_to_image(1, read=False, write=True)
            for name, value in uniforms.items():
                if name in program:  # the driver may drop one the GLSL does not need
                    set_uniform(program, name, value)
            set_uniform(program, "u_layers", stack.layers)
            self._run(program, region or Region(0, 0, *stack.shape))
        return GpuStack(target, stack.layers, stack.shape)

    # ------------------------------------------------------------------ decode
    def decode(
        self, stack: GpuStack, plan: DecodePlan, region: Region | None = None
    ) -> list[DirectionMaps]:
        """Each direction of ``plan`` decoded over ``region`` (default: the image): its
        maps, read back (the frames themselves stay on the GPU)."""
        periods, shifts = len(plan.periods_mm), len(plan.steps_rad)
        directions = len(plan.first_layers)
        program = self._program(
            ("decode", periods, shifts, directions),
            "passes/decode.comp.glsl",
            (),
            periods=periods,
            shifts=shifts,
            directions=directions,
        )
        area = region or Region(0, 0, *stack.shape)
        count = directions * plan.layers_per_direction
        with self.context.current():
            maps = self._array("maps", (area.rows, area.cols), count)
            stack.texture.bind_to_image(0, read=True, write=False)
            maps.bind_to_image(1, read=False, write=True)
            values: dict[str, object] = {
                "u_first_layer": list(plan.first_layers),
                "u_extent_mm": list(plan.extents_mm),
                "u_periods_mm": list(plan.periods_mm),
                "u_sin": [math.sin(step) for step in plan.steps_rad],
                "u_cos": [math.cos(step) for step in plan.steps_rad],
                "u_threshold": float(plan.threshold),
            }
            for name, value in values.items():
                if name in program:
                    set_uniform(program, name, value)
            self._run(program, area)
            out = np.empty((count, area.rows, area.cols), np.float32)
            maps.read_into(out)
        per = plan.layers_per_direction
        return [_direction_maps(out[d * per : (d + 1) * per], periods) for d in range(directions)]


def _direction_maps(layers: np.ndarray, periods: int) -> DirectionMaps:
    return DirectionMaps(
        sine=layers[0].astype(np.float64) + layers[2],
        cosine=layers[1].astype(np.float64) + layers[3],
        coarse=layers[4],
        valid=layers[5] > 0.5,
        modulation=layers[6 : 6 + periods],
        offset=layers[6 + periods : 6 + 2 * periods],
        wrapped=layers[6 + 2 * periods : 6 + 3 * periods],
    )
