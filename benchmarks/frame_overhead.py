"""Per-frame time of the renderer: a 512² uv frame (GPU-bound) and a 16² frame (the CPU
work around a draw: scene, features, uniforms, read-back). docs/BENCHMARKS.md,
"The component registry".

    python benchmarks/frame_overhead.py
"""

from __future__ import annotations

import statistics
import time

from glshade import paper_scene
from glshade.gpu.renderer import Renderer


def main() -> None:
    scene = paper_scene("sphere", 15, 4, 0.005).with_size(512)
    with Renderer() as renderer:
        renderer.render(scene, ("uv",))
        times = []
        for i in range(15):
            shifted = scene.with_phase(i * 0.01)
            start = time.perf_counter()
            renderer.render(shifted, ("uv",))
            times.append(time.perf_counter() - start)
        small = scene.with_size(16)
        renderer.render(small)
        start = time.perf_counter()
        for i in range(300):
            renderer.render(small.with_phase(i * 0.001))
        overhead = (time.perf_counter() - start) / 300
    print(
        f"512² uv frame: median {statistics.median(times) * 1e3:.2f} ms; 16² frame: mean "
        f"{overhead * 1e6:.0f} µs"
    )


if __name__ == "__main__":
    main()
