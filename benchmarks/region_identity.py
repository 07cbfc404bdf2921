"""The dent's region of influence against the full frame, on every case of the paper's study.

Each case's emitter maps are traced once; the same maps are then measured twice, by a
baseline that analyses the whole frame (``full_frame=True``, the reference) and by one that
works in the dent's region of influence (the default). Every number of the result, its
status and the per-phase comparisons must be identical; the analysis times are printed
per surface (best of ``--repeats`` runs per case, one thread).

    python benchmarks/region_identity.py                 # the study: 216 cases at 1024²
    python benchmarks/region_identity.py --size 256 --surfaces flat

Exit code 1 when a case differs.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

import numpy as np

from glshade.gpu.renderer import Renderer
from glshade.instruments.stripes.single import emitter_map, judged
from glshade.metrics import visibility as vis
from glshade.study.plan import StudyPlan


def best_of(
    repeats: int, scene, baseline: vis.Baseline, v1: np.ndarray
) -> tuple[float, vis.Visibility]:
    """The shortest of ``repeats`` measurements of a case, status included (seconds), and
    the last result."""
    times, result = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        result = judged(scene, baseline, v1, baseline.measure(v1))
        times.append(time.perf_counter() - start)
    assert result is not None
    return min(times), result


def differences(full: vis.Visibility, region: vis.Visibility) -> list[str]:
    """The fields of two results that differ (:data:`glshade.metrics.visibility.
    RESULT_FIELDS`), and the displacement map where the region searched it (elsewhere it
    reads 0 by design)."""
    found = vis.differing_fields(full, region)
    searched = region.displacement_px > 0
    if not np.array_equal(full.displacement_px[searched], region.displacement_px[searched]):
        found.append("displacement_px (searched pixels)")
    return found


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--surfaces", default="flat,cylinder,sphere")
    args = parser.parse_args()
    plan = StudyPlan(surfaces=tuple(args.surfaces.split(",")), size=args.size)
    settings = vis.MetricSettings()
    seconds: dict[str, tuple[list[float], list[float]]] = {}
    failed = 0
    with Renderer() as renderer:
        baselines: dict[tuple, tuple[vis.Baseline, vis.Baseline]] = {}
        for point in plan.cases():
            surface, theta = point[0], point[1]
            scene = plan.scene(*point)
            if (surface, theta) not in baselines:
                normal = scene.without_defect()
                v0 = emitter_map(renderer, normal)
                pattern = scene.active.emitter.pattern(scene)
                baselines[(surface, theta)] = (
                    vis.Baseline(v0, pattern, settings, full_frame=True),
                    vis.Baseline(v0, pattern, settings),
                )
            full_base, region_base = baselines[(surface, theta)]
            v1 = emitter_map(renderer, scene)
            full_s, full = best_of(args.repeats, scene, full_base, v1)
            region_s, region = best_of(args.repeats, scene, region_base, v1)
            spent = seconds.setdefault(surface, ([], []))
            spent[0].append(full_s)
            spent[1].append(region_s)
            found = differences(full, region)
            if found:
                failed += 1
                print(f"DIFFERS {point}: {', '.join(found)}")
    print(f"{'surface':<10} {'cases':>5} {'full frame ms':>14} {'region ms':>10} {'speed-up':>9}")
    for surface, (full_s, region_s) in seconds.items():
        full_ms, region_ms = statistics.mean(full_s) * 1e3, statistics.mean(region_s) * 1e3
        print(
            f"{surface:<10} {len(full_s):>5} {full_ms:>14.1f} {region_ms:>10.1f} "
            f"{full_ms / region_ms:>8.2f}x"
        )
    every_full = [s for full_s, _ in seconds.values() for s in full_s]
    every_region = [s for _, region_s in seconds.values() for s in region_s]
    print(
        f"{'all':<10} {len(every_full):>5} {statistics.mean(every_full) * 1e3:>14.1f} "
        f"{statistics.mean(every_region) * 1e3:>10.1f}   (mean analysis per case, status included)"
    )
    print("identical in every field" if not failed else f"{failed} cases differ")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
