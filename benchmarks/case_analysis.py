"""One case's analysis, as the study measures it: every case of the paper's study traced
once, then measured against its geometry's defect-free analysis and given its status
(``judged(scene, baseline, v1, baseline.measure(v1))``), best of 3; the mean per surface.

It uses only what every version of glshade has, so two versions compare back to back:

    python benchmarks/case_analysis.py
    PYTHONPATH=OLD/src python benchmarks/case_analysis.py    # a worktree of another commit
"""

from __future__ import annotations

import statistics
import time

from glshade.gpu.renderer import Renderer
from glshade.instruments.stripes.single import emitter_map, judged, map_baseline
from glshade.metrics import visibility as vis
from glshade.study.plan import StudyPlan

REPEATS = 3


def main() -> None:
    plan = StudyPlan()
    settings = vis.MetricSettings()
    seconds: dict[str, list[float]] = {}
    with Renderer() as renderer:
        baselines = {}
        for point in plan.cases():
            scene = plan.scene(*point)
            if point[:2] not in baselines:
                normal = scene.without_defect()
                baselines[point[:2]] = map_baseline(normal, emitter_map(renderer, normal), settings)
            baseline = baselines[point[:2]]
            v1 = emitter_map(renderer, scene)
            times = []
            for _ in range(REPEATS):
                start = time.perf_counter()
                judged(scene, baseline, v1, baseline.measure(v1))
                times.append(time.perf_counter() - start)
            seconds.setdefault(point[0], []).append(min(times))
    every = [s for spent in seconds.values() for s in spent]
    for name, spent in [*seconds.items(), ("all", every)]:
        print(
            f"{name:<10} {len(spent):>4} cases: {statistics.mean(spent) * 1e3:6.1f} ms mean, "
            f"{statistics.median(spent) * 1e3:6.1f} ms median"
        )


if __name__ == "__main__":
    main()
