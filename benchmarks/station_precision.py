"""Posed stations against the NumPy fp64 oracle, and their frame time: the overhead
station of ``examples/overhead_station.toml`` (a screen above the part, the camera off its
mirror plane) and the SOFAST-like station of ``examples/sofast_like_station.toml`` (a
camera beside a screen of 8.7 m x 3.5 m, 10 m above a concave facet of 200 m radius at
near-normal incidence), fp32 and fp64.

The renderer draws the whole frame (median of 5 after a warm-up); the oracle traces a
band of ``--rows`` rows through the centre. Prints a markdown table: the largest uv error
(mm on the screen) over the pixels both see, the mask disagreements, and ms per frame.

    python benchmarks/station_precision.py --size 1024 --rows 16
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

from glshade.gpu.renderer import Renderer
from glshade.oracle import tracer
from glshade.scene import Scene

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


STATIONS = {
    "overhead (0.2 m)": lambda: Scene.load(EXAMPLES / "overhead_station.toml"),
    "SOFAST-like (10 m)": lambda: Scene.load(EXAMPLES / "sofast_like_station.toml"),
}


def frame_ms(renderer: Renderer, scene: Scene, repeats: int = 5) -> float:
    renderer.render(scene, ("uv",))
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        renderer.render(scene, ("uv",))
        times.append(time.perf_counter() - start)
    return 1000.0 * statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--rows", type=int, default=16)
    args = parser.parse_args()
    band = slice(args.size // 2 - args.rows // 2, args.size // 2 + (args.rows + 1) // 2)
    with Renderer() as renderer:
        print(f"{renderer.context.info().renderer}, {args.size}², oracle band of {args.rows} rows")
        print("| station | precision | uv max error (mm) | mask disagreements | ms / frame |")
        print("|---|---|---:|---:|---:|")
        for name, build in STATIONS.items():
            base = build().with_size(args.size)
            expected = tracer.trace(base, ("uv", "mask"), rows=band)
            for precision in ("fp32", "fp64"):
                scene = base.updated(render={"precision": precision})
                frame = renderer.render(scene, ("uv", "mask"))
                both = frame.mask[band] & expected.mask
                error = float(np.abs(frame.uv[band] - expected.uv)[both].max())
                wrong = int((frame.mask[band] != expected.mask).sum())
                ms = frame_ms(renderer, scene)
                print(f"| {name} | {precision} | {error:.3g} | {wrong} | {ms:.1f} |")


if __name__ == "__main__":
    main()
