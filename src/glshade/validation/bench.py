"""Render benchmark: the paper's flat scene, fp32 and fp64 shaders against the NumPy
reference, in one run (``glshade bench``; figures go to ``docs/BENCHMARKS.md``).

Timings are medians of wall time per frame, read-back into NumPy included, after one
warm-up frame (which compiles the program). The reference is timed on the same scene;
``reference_rows`` traces only a band of rows and scales the time per pixel, which the
report says when it happens.
"""

from __future__ import annotations

import platform
import statistics
import time
from dataclasses import dataclass

from glshade.gpu.context import GLContext
from glshade.gpu.renderer import Renderer
from glshade.scene import Scene, paper_scene


@dataclass(frozen=True)
class Timing:
    label: str
    seconds: float  # median per frame
    pixels: int

    @property
    def megapixels_per_second(self) -> float:
        return self.pixels / self.seconds / 1e6


def _median_seconds(fn, repeats: int) -> float:
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        samples.append(time.perf_counter() - start)
    return statistics.median(samples)


def run(
    size: int = 1024,
    theta_deg: float = 45.0,
    repeats: int = 9,
    reference_rows: int | None = None,
    device_index: int | None = None,
    outputs: tuple[str, ...] = ("image",),
) -> tuple[list[Timing], str]:
    """Time fp32, fp64 and the NumPy reference; returns the timings and the GL renderer."""
    from glshade.oracle import tracer as reference

    base = paper_scene("flat", theta_deg, 4.0, 0.005).with_size(size)
    pixels = base.camera.width * base.camera.height
    timings = []
    with GLContext(device_index=device_index) as context, Renderer(context) as renderer:
        gl_renderer = context.info().renderer
        for precision in ("fp32", "fp64"):
            scene: Scene = base.updated(render={"precision": precision})
            renderer.render(scene, outputs)  # compile + warm up
            seconds = _median_seconds(lambda scene=scene: renderer.render(scene, outputs), repeats)
            timings.append(Timing(f"shader {precision}", seconds, pixels))
    rows = size if reference_rows is None else min(reference_rows, size)
    start = time.perf_counter()
    reference.trace(base, outputs, rows=slice((size - rows) // 2, (size - rows) // 2 + rows))
    seconds = (time.perf_counter() - start) * size / rows
    label = "NumPy reference fp64" + ("" if rows == size else f" ({rows} rows, scaled)")
    timings.append(Timing(label, seconds, pixels))
    return timings, gl_renderer


def report(
    timings: list[Timing], gl_renderer: str, size: int, theta_deg: float, repeats: int
) -> str:
    """A markdown table of the frame times, with each renderer's speed-up over the NumPy
    reference and its time relative to the fp32 shader."""
    reference = timings[-1].seconds
    fp32 = timings[0].seconds
    lines = [
        f"Scene: paper flat, theta {theta_deg:g} deg, sigma2 4 mm², dmax 0.005 mm, "
        f"{size}x{size}, image only.",
        (
            f"GL renderer: {gl_renderer}; CPU: {platform.processor() or platform.machine()}; "
            f"median of {repeats} frames after a warm-up."
        ),
        "",
        "| renderer | ms / frame | Mpixel/s | vs NumPy reference | vs shader fp32 |",
        "|---|---:|---:|---:|---:|",
    ]
    for t in timings:
        lines.append(
            f"| {t.label} | {t.seconds * 1e3:.1f} | {t.megapixels_per_second:.2f} | "
            f"{reference / t.seconds:.1f}x faster | {t.seconds / fp32:.2f}x time |"
        )
    return "\n".join(lines)
