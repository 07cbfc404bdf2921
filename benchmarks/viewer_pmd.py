"""How long the viewer's PMD view takes to follow a change. docs/BENCHMARKS.md, "The
viewer's PMD view".

Drives the viewer's model (no window: the station measures in a thread of its own with
a renderer of its own, as in the window) in the PMD phase view of the paper's scene, and
times, from the change to the result being taken: the first case (the station's
renderer made, its programs compiled, the defect-free analysis and the case), a change
of the dent alone (the defect-free analysis kept: one sequence rendered and decoded),
and a change of θ (a new geometry: both sequences). Each a few times; the median.

    python benchmarks/viewer_pmd.py [--size 512] [--pmd-size 256 512] [--repeats 3]
"""

from __future__ import annotations

import argparse
import statistics
import time

from glshade.app.viewer.model import ViewerModel
from glshade.scene import paper_scene


def _settled(model: ViewerModel) -> float:
    """Seconds from now until the station's case is taken (the window's loop polls)."""
    start = time.perf_counter()
    model.start_metrics()
    while True:
        if model.collect_metrics() and model.cases.job is None:
            return time.perf_counter() - start
        time.sleep(1 / 30)


def run(size: int, pmd_size: int, repeats: int) -> dict[str, float]:
    model = ViewerModel(paper_scene().with_size(size), view="pmd-phase", case_size=pmd_size)
    times = {"first": _settled(model), "dent": [], "theta": []}
    for i in range(repeats):
        model.set("dmax", 0.004 + 0.0005 * i)
        times["dent"].append(_settled(model))
        model.set("theta", 40.0 + i)
        times["theta"].append(_settled(model))
    model.close()
    return {k: v if isinstance(v, float) else statistics.median(v) for k, v in times.items()}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--pmd-size", type=int, nargs="+", default=[256, 512])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    print("| image | PMD case | first case | dent changed | theta changed |")
    print("|---|---|---:|---:|---:|")
    for pmd_size in args.pmd_size:
        t = run(args.size, pmd_size, args.repeats)
        print(
            f"| {args.size}² | {pmd_size}² | {t['first']:.2f} s | {t['dent']:.2f} s | "
            f"{t['theta']:.2f} s |"
        )


if __name__ == "__main__":
    main()
