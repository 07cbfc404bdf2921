"""The metric's per-phase work, CPU or shader (docs/BENCHMARKS.md, "The metric's per-phase
work: CPU or shader").

At each phase of the sweep the paper's metric binarises the emitter map ``v`` inside the
kept columns (``Baseline.binary``) and takes, per column, the first and last row of every
white run (the crossing rows that ``contours.find_stripes`` keeps as ``top``/``bottom``).
This measures that job for every phase of one defect's map (the paper's flat plate and
sphere at θ 45°), these ways:

- ``cpu``: NumPy, as the metric does it today, on the read-back map (``cpu (binarise
  alone)``: its first half, the part a shader would take over);
- ``gpu layers``: a compute shader writes every phase's binary image (one R8UI layer each)
  from the uv render target still on the GPU; they are read back; the crossings on the CPU;
- ``gpu bits``: the same into bit planes (32 pixels a uint), unpacked with NumPy;
- ``gpu bits+crossings``: the bit planes, and a second kernel that finds the crossings in
  them (an SSBO filled through one atomic counter); both read back: nothing per phase is
  left to the CPU but unpacking the bits (the labelling needs the image) and the rows;
- ``gpu crossings``: the same two kernels, only the crossings read back (not enough for
  the labelling: what the crossings alone would cost).

Each runs on the full frame and on a band of ``--band`` of the rows (`` band``; the
region-of-influence analysis). Every GPU result is checked pixel for pixel (binary
images) and crossing for crossing against the CPU's, which is itself checked against
``Baseline.binary`` and ``find_stripes``. Times are medians of ``--repeats`` rounds after
a warm-up, every path once a round (a busy spell on the shared cores hits them alike);
``core ms`` is the process's CPU time (llvmpipe's threads included): with the GL thread
and the analysing threads sharing the cores, that is what a study pays.

    python benchmarks/gpu_binarise.py [--size 1024] [--repeats 7] [--band 0.3]
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import moderngl
import numpy as np

from glshade.gpu.renderer import Renderer, drawn_features
from glshade.instruments.stripes.single import emitter_map, map_baseline
from glshade.metrics import contours as ct
from glshade.metrics.visibility import Baseline, MetricSettings, binarize_v
from glshade.scene import Scene, paper_scene

GLSL = Path(__file__).resolve().parent / "glsl"
MAX_PHASES = 64  # as shaders' MAX_PHASES


# --------------------------------------------------------------------------- the job
@dataclass(frozen=True)
class Crossings:
    """One phase's crossing rows: ``top`` and ``bottom`` pixels as flat indices of the
    band's cut image (the CPU finds them in row-major order, as ``contours._runs`` does;
    the GPU in blocks of 32 columns; the metric's uses of them do not depend on order)."""

    top: np.ndarray
    bottom: np.ndarray

    def same_as(self, other: Crossings) -> bool:
        """The same pixels, whatever their order."""
        return all(
            np.array_equal(np.sort(mine), np.sort(theirs))
            for mine, theirs in ((self.top, other.top), (self.bottom, other.bottom))
        )


def crossings_of(binary: np.ndarray) -> Crossings:
    """The first and last pixel of every white run of each column (bool image): what
    ``find_stripes`` computes from its labels, since vertically adjacent white pixels
    always share a label."""
    starts = binary.copy()
    starts[1:] &= ~binary[:-1]
    ends = binary.copy()
    ends[:-1] &= ~binary[1:]
    return Crossings(np.flatnonzero(starts), np.flatnonzero(ends))


def rows_cols(flat: np.ndarray, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Row and column arrays of flat indices (what ``_runs`` hands on)."""
    return np.divmod(flat, width)


def cpu_binary(baseline: Baseline, v: np.ndarray, phase_mm: float, rows: slice) -> np.ndarray:
    """``Baseline.binary`` restricted to ``rows`` (bool)."""
    assert baseline.half_width_mm is not None
    cut = v[rows, baseline.columns]
    white = binarize_v(cut, baseline.pattern, phase_mm, baseline.half_width_mm)
    return white & baseline.valid[rows]


def cpu_job(baseline: Baseline, v: np.ndarray, rows: slice) -> list[tuple[np.ndarray, Crossings]]:
    """Every phase's binary image and crossing rows, NumPy."""
    out = []
    width = baseline.valid.shape[1]
    for phase in baseline.phases:
        binary = cpu_binary(baseline, v, float(phase), rows)
        found = crossings_of(binary)
        rows_cols(found.top, width)  # made as _runs makes them; only timed here
        rows_cols(found.bottom, width)
        out.append((binary, found))
    return out


# --------------------------------------------------------------------------- the shaders
def compute_program(ctx: moderngl.Context, kernel: str) -> moderngl.ComputeShader:
    """The binarisation header followed by a kernel (two files, compiled as one text)."""
    source = (GLSL / "stripe_bit.glsl").read_text() + "\n" + (GLSL / kernel).read_text()
    return ctx.compute_shader(source)


@dataclass(frozen=True)
class Timed:
    """Stage times of one run (seconds) and the bytes read back."""

    shader: float
    read: float
    cpu: float
    read_bytes: int


#: Binary images of every phase: (phases, rows, cols) bool, or one (rows, cols) per phase.
Images = np.ndarray | Sequence[np.ndarray]
#: What a path gives: its binary images, its crossings, and the seconds of its stages.
Result = tuple[Images | None, list[Crossings] | None, Timed]


class GpuBinariser:
    """The per-phase job on the GPU for one baseline and one band of rows, from the uv
    render target (``uv_texture``: RG32F, .g = v) of the renderer's context."""

    def __init__(self, ctx: moderngl.Context, baseline: Baseline, rows: slice) -> None:
        assert baseline.half_width_mm is not None and len(baseline.phases) <= MAX_PHASES
        self.ctx = ctx
        self.baseline = baseline
        self.row0, self.rows = rows.start, rows.stop - rows.start
        self.cols = baseline.valid.shape[1]
        self.phases = len(baseline.phases)
        self.words = -(-self.cols // 32)
        valid = np.ascontiguousarray(baseline.valid, np.uint8)  # full height: rows index it
        self.valid = ctx.texture((self.cols, valid.shape[0]), 1, data=valid.tobytes(), dtype="u1")
        self.valid.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.programs = {
            name: compute_program(ctx, f"{name}.comp.glsl")
            for name in ("binarise_layers", "binarise_bits", "crossings")
        }
        for program in self.programs.values():
            self._set_uniforms(program)
        self.layers = ctx.texture_array((self.cols, self.rows, self.phases), 1, dtype="u1")
        self.bits = ctx.texture_array((self.words, self.rows, self.phases), 1, dtype="u4")
        self.capacity = self.phases * self.cols * 64  # entries; enlarged when a run overflows
        self.found = ctx.buffer(reserve=4 * self.capacity)
        self.table = ctx.buffer(reserve=16 * self.phases * self.words)
        self.used = ctx.buffer(reserve=8)

    def release(self) -> None:
        for program in self.programs.values():
            program.release()
        for texture in (self.valid, self.layers, self.bits):
            texture.release()
        for buffer in (self.found, self.table, self.used):
            buffer.release()

    def _set_uniforms(self, program: moderngl.ComputeShader) -> None:
        b = self.baseline
        assert b.half_width_mm is not None
        phases = np.zeros(MAX_PHASES, np.float32)
        phases[: self.phases] = b.phases  # float32, as NumPy rounds them
        values: dict[str, object] = {
            "u_uv": 0,
            "u_valid": 1,
            "u_col0": b.columns.start,
            "u_cols": self.cols,
            "u_row0": self.row0,
            "u_rows": self.rows,
            "u_phases": self.phases,
            "u_period": float(np.float32(b.pattern.period_mm)),
            "u_limit": float(np.float32(b.half_width_mm / b.pattern.period_mm)),
        }
        for name, value in values.items():
            if name in program:
                program[name].value = value
        if "u_phase" in program:
            program["u_phase"].write(phases.tobytes())  # type: ignore[union-attr]

    def _bind(self, uv_texture: moderngl.Texture) -> None:
        uv_texture.use(location=0)
        self.valid.use(location=1)

    def _run(self, name: str, groups: tuple[int, int]) -> None:
        self.programs[name].run(*groups, 1)

    # ---------------------------------------------------------------- binary images
    def binary_layers(self, uv_texture: moderngl.Texture) -> tuple[np.ndarray, Timed]:
        """(phases, rows, cols) bool, one R8UI layer per phase."""
        start = time.perf_counter()
        self._bind(uv_texture)
        self.layers.bind_to_image(0, read=False, write=True)
        self._run("binarise_layers", (-(-self.cols // 16), -(-self.rows // 4)))
        self.ctx.finish()
        shaded = time.perf_counter()
        self.ctx.memory_barrier()
        out = np.empty((self.phases, self.rows, self.cols), np.uint8)
        self.layers.read_into(out)
        read = time.perf_counter()
        return out.view(bool), Timed(shaded - start, read - shaded, 0.0, out.nbytes)

    def _shade_bits(self, uv_texture: moderngl.Texture) -> None:
        self._bind(uv_texture)
        self.bits.bind_to_image(0, read=False, write=True)
        self._run("binarise_bits", (-(-self.words // 4), -(-self.rows // 16)))

    def _read_bits(self) -> np.ndarray:
        self.ctx.memory_barrier()
        words = np.empty((self.phases, self.rows, self.words), np.uint32)
        self.bits.read_into(words)
        return words

    def _unpack(self, words: np.ndarray) -> np.ndarray:
        pixels = np.unpackbits(words.view(np.uint8), axis=-1, bitorder="little")
        return pixels[..., : self.cols].view(bool)

    def binary_bits(self, uv_texture: moderngl.Texture) -> tuple[np.ndarray, Timed]:
        """(phases, rows, cols) bool, from bit planes of 32 pixels a uint."""
        start = time.perf_counter()
        self._shade_bits(uv_texture)
        self.ctx.finish()
        shaded = time.perf_counter()
        words = self._read_bits()
        read = time.perf_counter()
        binary = self._unpack(words)
        done = time.perf_counter()
        return binary, Timed(shaded - start, read - shaded, done - read, words.nbytes)

    # ---------------------------------------------------------------- crossings
    def crossings(self, uv_texture: moderngl.Texture, with_binary: bool) -> Result:
        """Every phase's crossing rows (the bit planes, then the crossings kernel on them),
        and with ``with_binary`` the binary images too (the bit planes read back)."""
        start = time.perf_counter()
        while True:
            self._shade_bits(uv_texture)
            self.ctx.memory_barrier()
            self.bits.bind_to_image(0, read=True, write=False)
            self.used.write(np.array([0, self.capacity], np.uint32).tobytes())
            self.found.bind_to_storage_buffer(0)
            self.table.bind_to_storage_buffer(1)
            self.used.bind_to_storage_buffer(2)
            self._run("crossings", (-(-self.words // 8), -(-self.phases // 8)))
            self.ctx.finish()
            self.ctx.memory_barrier()
            used = int(np.frombuffer(self.used.read(4), np.uint32)[0])
            if used <= self.capacity:
                break
            self.capacity = 2 * used
            self.found.orphan(4 * self.capacity)
            start = time.perf_counter()  # the first run only sized the buffer
        shaded = time.perf_counter()
        found = np.empty(0, np.uint32)  # a read of 0 bytes cannot map the buffer
        if used:
            found = np.frombuffer(self.found.read(4 * used), np.uint32)
        table = np.frombuffer(self.table.read(), np.uint32).reshape(self.phases, self.words, 4)
        words = self._read_bits() if with_binary else None
        read = time.perf_counter()
        binary = self._unpack(words) if words is not None else None
        crossings = self._decode(found, table)
        done = time.perf_counter()
        nbytes = 4 * used + table.nbytes + (words.nbytes if words is not None else 0)
        return binary, crossings, Timed(shaded - start, read - shaded, done - read, nbytes)

    def _decode(self, found: np.ndarray, table: np.ndarray) -> list[Crossings]:
        """Flat indices per phase from the kernel's (offset, tops, bottoms) per word (each
        word's crossings in row-major order, the words one after another), with their rows
        and columns as ``_runs`` hands them on."""
        offset = table[..., 0].astype(np.int64)
        tops, bottoms = table[..., 1].astype(np.int64), table[..., 2].astype(np.int64)
        kinds = []
        for first, count in ((offset, tops), (offset + tops, bottoms)):
            flat = found[_ranges(first.ravel(), count.ravel())].astype(np.int64)
            rows_cols(flat, self.cols)  # made as _runs makes them; only timed here
            kinds.append(np.split(flat, np.cumsum(count.sum(axis=1))[:-1]))
        return [Crossings(top, bottom) for top, bottom in zip(*kinds, strict=True)]


def _ranges(first: np.ndarray, count: np.ndarray) -> np.ndarray:
    """Concatenated ``arange(first[i], first[i] + count[i])``."""
    starts = np.cumsum(count) - count
    return np.repeat(first - starts, count) + np.arange(int(count.sum()))


# --------------------------------------------------------------------------- a case
@dataclass(frozen=True)
class Case:
    """One defect's map at the renderer's resolution, its baseline, and its uv target."""

    surface: str
    scene: Scene
    baseline: Baseline
    v1: np.ndarray
    uv_texture: moderngl.Texture


def prepare(renderer: Renderer, surface: str, size: int) -> Case:
    """Render the defect-free map (the baseline) and then the defect's map, whose uv target
    stays bound to the renderer's cached render targets."""
    scene = paper_scene(surface, 45.0, 4.0, 0.005).with_size(size)
    baseline = map_baseline(scene, emitter_map(renderer, scene.without_defect()), MetricSettings())
    v1 = emitter_map(renderer, scene)
    # The renderer keeps its uv target after the draw; benchmarks may reach for it (a
    # production path would need the renderer to hand it out).
    targets = renderer._render_targets(size, size, drawn_features(scene, ("uv",)))
    return Case(surface, scene, baseline, v1, targets.textures[0])


def band_rows(height: int, fraction: float) -> slice:
    rows = max(1, round(height * fraction))
    start = (height - rows) // 2
    return slice(start, start + rows)


@dataclass(frozen=True)
class Row:
    """One line of the table: medians (ms) and whether it agreed with the CPU."""

    surface: str
    phases: int
    path: str
    rows: int
    shader_ms: float
    read_ms: float
    cpu_ms: float
    wall_ms: float
    best_ms: float
    core_ms: float
    read_mib: float
    identical: str


def interleaved(
    paths: dict[str, Callable[[], Result]], repeats: int
) -> dict[str, tuple[list[tuple[float, float, Timed]], Result]]:
    """Each path ``repeats`` times after a warm-up, in rounds that run every path once (in
    a rotating order, so that a busy spell on the shared cores hits them all alike): per
    path the (wall s, process CPU s, stages) of each run and its last result."""
    names = list(paths)
    last = {name: paths[name]() for name in names}
    samples: dict[str, list[tuple[float, float, Timed]]] = {name: [] for name in names}
    for index in range(repeats):
        turn = index % len(names)
        for name in names[turn:] + names[:turn]:
            wall, core = time.perf_counter(), time.process_time()
            last[name] = paths[name]()
            wall, core = time.perf_counter() - wall, time.process_time() - core
            samples[name].append((wall, core, last[name][2]))
    return {name: (samples[name], last[name]) for name in names}


def check_cpu(case: Case) -> None:
    """The CPU job equals the metric's own functions (full frame)."""
    b = case.baseline
    full = slice(0, case.v1.shape[0])
    for phase, (binary, found) in zip(b.phases, cpu_job(b, case.v1, full), strict=True):
        assert np.array_equal(binary, b.binary(case.v1, float(phase)))
        stripes = ct.find_stripes(binary, b.edge)
        width = binary.shape[1]
        assert np.array_equal(found.top, stripes.top.rows * width + stripes.top.cols)
        assert np.array_equal(found.bottom, stripes.bottom.rows * width + stripes.bottom.cols)


def paths_for(case: Case, gpu: GpuBinariser, rows: slice) -> dict[str, Callable[[], Result]]:
    """The ways to do one band's per-phase job, each giving (binary images, crossings,
    stage seconds)."""
    b, v1, tex, width = case.baseline, case.v1, case.uv_texture, gpu.cols

    def cpu() -> Result:
        start = time.perf_counter()
        job = cpu_job(b, v1, rows)
        spent = time.perf_counter() - start
        return [binary for binary, _ in job], [found for _, found in job], Timed(0, 0, spent, 0)

    def cpu_binarise() -> Result:
        start = time.perf_counter()
        binary = [cpu_binary(b, v1, float(phase), rows) for phase in b.phases]
        return binary, None, Timed(0, 0, time.perf_counter() - start, 0)

    def with_cpu_crossings(shade: Callable[[], tuple[np.ndarray, Timed]]) -> Result:
        binary, t = shade()
        start = time.perf_counter()
        found = [_finish(binary[k], width) for k in range(gpu.phases)]
        spent = t.cpu + time.perf_counter() - start
        return binary, found, Timed(t.shader, t.read, spent, t.read_bytes)

    return {
        "cpu": cpu,
        "cpu (binarise alone)": cpu_binarise,
        "gpu layers": lambda: with_cpu_crossings(lambda: gpu.binary_layers(tex)),
        "gpu bits": lambda: with_cpu_crossings(lambda: gpu.binary_bits(tex)),
        "gpu bits+crossings": lambda: gpu.crossings(tex, with_binary=True),
        "gpu crossings": lambda: gpu.crossings(tex, with_binary=False),
    }


def measure(case: Case, ctx: moderngl.Context, band: float, repeats: int) -> list[Row]:
    """The table's rows for one case: every path on the full frame and on the band, each
    checked against the CPU's binary images and crossings."""
    height = case.v1.shape[0]
    table: list[Row] = []
    for label, rows in (("", slice(0, height)), (" band", band_rows(height, band))):
        gpu = GpuBinariser(ctx, case.baseline, rows)
        measured = interleaved(paths_for(case, gpu, rows), repeats)
        _, (expect_binary, expect_found, _) = measured["cpu"]
        assert expect_binary is not None and expect_found is not None
        for name, (samples, (binary, found, _)) in measured.items():
            if name.startswith("cpu"):
                identical = "reference"
            else:
                same = binary is None or _same_binary(binary, expect_binary)
                same = same and found is not None and _same_crossings(found, expect_found)
                identical = "yes" if same else "NO"
            table.append(_row(case.surface, gpu, name + label, samples, identical))
        gpu.release()
    return table


def _row(surface: str, gpu: GpuBinariser, path: str, samples: list, identical: str) -> Row:
    walls = [wall for wall, _, _ in samples]
    stages = [t for _, _, t in samples]
    return Row(
        surface, gpu.phases, path, gpu.rows,
        statistics.median(t.shader for t in stages) * 1e3,
        statistics.median(t.read for t in stages) * 1e3,
        statistics.median(t.cpu for t in stages) * 1e3,
        statistics.median(walls) * 1e3, min(walls) * 1e3,
        statistics.median(core for _, core, _ in samples) * 1e3,
        stages[-1].read_bytes / (1 << 20), identical,
    )  # fmt: skip


def _finish(binary: np.ndarray, width: int) -> Crossings:
    found = crossings_of(binary)
    rows_cols(found.top, width)
    rows_cols(found.bottom, width)
    return found


def _same_binary(found: Images, expect: Images) -> bool:
    return len(found) == len(expect) and all(
        np.array_equal(a, b) for a, b in zip(found, expect, strict=True)
    )


def _same_crossings(found: list[Crossings], expect: list[Crossings]) -> bool:
    return len(found) == len(expect) and all(
        a.same_as(b) for a, b in zip(found, expect, strict=True)
    )


# --------------------------------------------------------------------------- context
def median_ms(action: Callable[[], object], repeats: int) -> float:
    """Median wall milliseconds of ``action`` after a warm-up."""
    action()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        action()
        times.append(time.perf_counter() - start)
    return statistics.median(times) * 1e3


def common_stages(renderer: Renderer, case: Case, repeats: int) -> dict[str, float]:
    """What every path pays alike (ms): the trace of the defect's uv map with its read-back,
    the read-back alone (the continuous metric needs the map on the CPU whatever
    binarises), and the labelling of every phase's binary image
    (cv2.connectedComponents), which stays on the CPU."""
    b = case.baseline
    height, width = case.v1.shape
    host = np.empty((height, width, 2), np.float32)
    binaries = [b.binary(case.v1, float(phase)).astype(np.uint8) for phase in b.phases]

    def label() -> None:
        for binary in binaries:
            cv2.connectedComponents(binary, connectivity=8, ltype=cv2.CV_32S)

    return {
        "trace + uv read-back": median_ms(lambda: renderer.render(case.scene, ("uv",)), repeats),
        "uv read-back": median_ms(lambda: case.uv_texture.read_into(host), repeats),
        "labelling (all phases)": median_ms(label, repeats),
    }


def print_table(table: list[Row]) -> None:
    print(
        "| surface | phases | path | rows | shader ms | read-back ms (MiB) | CPU ms "
        "| wall ms | best wall ms | core ms | identical to CPU |"
    )
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---|")
    for r in table:
        print(
            f"| {r.surface} | {r.phases} | {r.path} | {r.rows} | {r.shader_ms:.1f} | "
            f"{r.read_ms:.1f} ({r.read_mib:.2f}) | {r.cpu_ms:.1f} | **{r.wall_ms:.1f}** | "
            f"{r.best_ms:.1f} | "
            f"{r.core_ms:.1f} | {r.identical} |"
        )


def parse(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=1024, help="pixels per side, 64-4096")
    parser.add_argument("--repeats", type=int, default=7, help="timed runs per path, 1-100")
    parser.add_argument("--band", type=float, default=0.3, help="band's share of rows, (0, 1]")
    args = parser.parse_args(argv)
    for name, ok, allowed in (
        ("--size", 64 <= args.size <= 4096, "an integer in [64, 4096]"),
        ("--repeats", 1 <= args.repeats <= 100, "an integer in [1, 100]"),
        ("--band", 0.0 < args.band <= 1.0, "a fraction in (0, 1]"),
    ):
        if not ok:
            print(f"{name}: must be {allowed}, got {getattr(args, name[2:])}", file=sys.stderr)
            raise SystemExit(2)
    return args


def main(argv: list[str] | None = None) -> None:
    args = parse(argv)
    table: list[Row] = []
    with Renderer() as renderer:
        ctx = renderer.context.gl
        load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
        print(
            f"GL renderer: {ctx.info['GL_RENDERER']}; {os.cpu_count()} cores, load average "
            f"{load} at the start; {args.size}², median of {args.repeats} rounds"
        )
        for surface in ("flat", "sphere"):
            case = prepare(renderer, surface, args.size)
            check_cpu(case)
            with renderer.context.current():
                table.extend(measure(case, ctx, args.band, args.repeats))
                common = common_stages(renderer, case, args.repeats)
            print(f"{surface}: common to every path: "
                  + ", ".join(f"{k} {v:.1f} ms" for k, v in common.items()))  # fmt: skip
    print_table(table)
    bad = [r for r in table if r.identical == "NO"]
    if bad:
        print("NOT identical to the CPU: " + ", ".join(f"{r.surface} {r.path}" for r in bad))
        raise SystemExit(1)
    print("Every GPU binary image and crossing list is identical to the CPU's (same pixels).")


if __name__ == "__main__":
    main()
