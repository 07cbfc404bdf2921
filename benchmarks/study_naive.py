"""The naive way to run the paper's study, for comparison with ``glshade paper``:
every phase of every case re-renders both images (defect and defect-free) on the GPU,
reads them back and runs the contour metric from scratch; nothing is shared.

Measured on a subset (each surface at θ = 85, 45, 5 with σ² 4, dmax 5 µm) at the
paper's 1024², extrapolated per surface to the 72 cases of Table 1.

    python benchmarks/study_naive.py
"""

from __future__ import annotations

import time

from glshade.gpu.renderer import Renderer
from glshade.metrics import visibility as vis
from glshade.scene import paper_scene

SUBSET_THETAS = (85.0, 45.0, 5.0)
CASES_PER_SURFACE = 9 * 4 * 2


def naive_case(
    renderer: Renderer, surface: str, theta: float, settings: vis.MetricSettings
) -> float:
    scene = paper_scene(surface, theta, 4.0, 0.005)
    start = time.perf_counter()
    vis.image_visibility(
        lambda p: renderer.render(scene.without_defect().with_phase(p)).image,
        lambda p: renderer.render(scene.with_phase(p)).image,
        scene.emitter.period,
        settings,
    )
    return time.perf_counter() - start


def main() -> None:
    settings = vis.MetricSettings()
    total = 0.0
    with Renderer() as renderer:
        renderer.render(paper_scene("flat"))  # compile outside the timing
        for surface in ("flat", "cylinder", "sphere"):
            renderer.render(paper_scene(surface))
            renderer.render(paper_scene(surface).without_defect())
            seconds = [naive_case(renderer, surface, t, settings) for t in SUBSET_THETAS]
            per_case = sum(seconds) / len(seconds)
            total += per_case * CASES_PER_SURFACE
            print(
                f"{surface}: {per_case:.2f} s per case (measured at θ "
                f"{', '.join(f'{t:g}' for t in SUBSET_THETAS)}), "
                f"x {CASES_PER_SURFACE} cases = {per_case * CASES_PER_SURFACE:.0f} s"
            )
    print(f"naive loop, extrapolated to the 216 cases: {total:.0f} s")


if __name__ == "__main__":
    main()
