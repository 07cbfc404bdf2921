"""Render time of the free-form surfaces against the analytic sphere (docs/BENCHMARKS.md).

At 1024² (the paper's camera, θ 45, the paper's dent): the paper's sphere, the sphere
sampled into 1024² and 4096² height maps (±30 mm, so 0.059 and 0.015 mm spacing), the
example panel (examples/panel.x3p, 640², 0.1 mm) and the saddle formula
(examples/saddle.toml's expression). Median of 9 frames after a warm-up (which compiles
the program and uploads the map), fp32 and fp64.

    python benchmarks/freeform_render.py
"""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from glshade.components.registry import registry
from glshade.errors import SceneError
from glshade.gpu.renderer import Renderer
from glshade.scene import Scene, paper_scene

ROOT = Path(__file__).resolve().parents[1]


def _median_ms(renderer: Renderer, scene: Scene, repeats: int = 9) -> float:
    renderer.render(scene)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        renderer.render(scene)
        times.append(time.perf_counter() - start)
    return 1e3 * statistics.median(times)


def scenes(directory: Path) -> list[tuple[str, Scene]]:
    sphere = paper_scene("sphere", theta_deg=45.0)
    out = [("analytic sphere", sphere)]
    for samples in (1024, 4096):
        axis = np.linspace(-30.0, 30.0, samples)
        xx, zz = np.meshgrid(axis, axis)
        path = directory / f"sphere_{samples}.npy"
        np.save(path, registry().active(sphere).surface.height(sphere, xx, zz))
        spacing = float(axis[1] - axis[0])
        out.append(
            (
                f"sphere as a {samples}² height map ({spacing:.3f} mm)",
                sphere.updated(
                    surface={"kind": "heightmap", "file": str(path), "spacing": (spacing, spacing)}
                ),
            )
        )
    out.append(
        (
            "example panel (640² x3p)",
            Scene.load(ROOT / "examples" / "panel.toml")
            .with_size(1024)
            .updated(camera={"theta_deg": 45.0}),
        )
    )
    out.append(
        (
            "saddle formula",
            Scene.load(ROOT / "examples" / "saddle.toml")
            .with_size(1024)
            .updated(camera={"theta_deg": 45.0}),
        )
    )
    return out


def main() -> None:
    with tempfile.TemporaryDirectory() as directory, Renderer() as renderer:
        print(f"{renderer.context.info().renderer}, 1024², θ 45°, median of 9 frames")
        print("| surface | fp32 ms | fp64 ms |")
        print("|---|---:|---:|")
        for label, scene in scenes(Path(directory)):
            fp32 = f"{_median_ms(renderer, scene):.0f}"
            try:
                fp64 = f"{_median_ms(renderer, scene.updated(render={'precision': 'fp64'})):.0f}"
            except SceneError:  # sin(): GLSL has no double version
                fp64 = "n/a (sin)"
            print(f"| {label} | {fp32} | {fp64} |")


if __name__ == "__main__":
    main()
