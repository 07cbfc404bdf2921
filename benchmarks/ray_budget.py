"""Every ray counted: brightness at many rays per pixel, and what splitting a pixel's rays
over draws costs per frame. docs/BENCHMARKS.md, "Every ray counted".

    python benchmarks/ray_budget.py            # brightness and frame times
    python benchmarks/ray_budget.py --times    # frame times only

Brightness: the mean of a 16 x 12 crop of the 256² camera (its pixel pitch) at many rays
per pixel over the same crop at 4 x 64 (a setting one draw traces whole on llvmpipe).
Frame times: medians of 25 renders (phases apart), the image only.
"""

from __future__ import annotations

import statistics
import sys
import time

from glshade import paper_scene
from glshade.gpu.renderer import Renderer

BRIGHTNESS = [
    ("flat mirror, the paper's dent", "flat+dent", 45.0, 16, 1024),
    ("flat mirror", "flat", 45.0, 16, 1024),
    ("flat mirror", "flat", 45.0, 12, 1024),
    ("flat mirror", "flat", 45.0, 8, 1024),
    ("sphere dent", "sphere", 45.0, 12, 1024),
    ("sphere dent", "sphere", 45.0, 16, 256),
    ("cylinder dent", "cylinder", 15.0, 16, 256),
]


def crop(shape: str, theta: float, supersample: int, samples: int):
    if shape == "flat+dent":  # the paper's flat scene: σ² 4, 5 µm
        scene = paper_scene("flat", theta, 4.0, 0.005).with_size(256)
    else:
        scene = paper_scene(shape, theta, 1.0, 0.005).with_size(256)
    if shape == "flat":
        scene = scene.without_defect()
    return scene.updated(
        camera={"width": 16, "height": 12, "f_number": 22.0, "aperture_samples": samples},
        render={"supersample": supersample},
    )


def median_ms(renderer: Renderer, scene, repeats: int = 25) -> float:
    renderer.render(scene)
    times = []
    for i in range(repeats):
        shifted = scene.with_phase(i * 0.01)
        start = time.perf_counter()
        renderer.render(shifted)
        times.append(time.perf_counter() - start)
    return statistics.median(times) * 1e3


def main() -> None:
    with Renderer() as renderer:
        if "--times" not in sys.argv:
            for name, shape, theta, n, k in BRIGHTNESS:
                reference = renderer.render(crop(shape, theta, 4, 64)).image.mean()
                start = time.perf_counter()
                image = renderer.render(crop(shape, theta, n, k)).image
                seconds = time.perf_counter() - start
                print(
                    f"{name} θ {theta:g} f/22, {n} x {k} rays: mean {image.mean():.4f} / "
                    f"{reference:.4f} at 4 x 64 = {image.mean() / reference:.3f} ({seconds:.1f} s)"
                )
        sphere = paper_scene("sphere", 15, 4, 0.005)
        frames = [
            ("512² sphere, supersample 1", sphere.with_size(512)),
            ("256² sphere, supersample 1", sphere.with_size(256)),
            (
                "256² sphere, supersample 2",
                sphere.with_size(256).updated(render={"supersample": 2}),
            ),
            (
                "256² sphere, f/8 lens, 16 samples",
                sphere.with_size(256).updated(camera={"f_number": 8.0, "aperture_samples": 16}),
            ),
        ]
        for name, scene in frames:
            print(f"{name}: median {median_ms(renderer, scene):.1f} ms")


if __name__ == "__main__":
    main()
