"""Cases per second of a phase-measuring sweep, in-process against Dask (docs/BENCHMARKS.md).

``examples/pmd_sweep.toml`` (a PMD station with a 12-bit sensor: 5 elevations x 3
phase-step counts = 15 cases, every case its own geometry) at ``--size`` pixels: in this
process, and on a LocalCluster of ``--workers`` single-threaded worker processes (the Dask
time includes starting the cluster, and each worker's first task its EGL context). Each
run starts from an empty output directory; the tables must be equal. Then where a case's
time goes (render, decode, heights), from the in-process run's case files.
``--dents K`` adds an axis of K dent depths (2 to 8 µm): K cases per geometry, which share
its defect-free analysis (in one Dask task of up to 16 cases, too).

    python benchmarks/pmd_sweep_throughput.py [--size 96] [--workers 2] [--repeats 2] [--dents K]
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
import tomllib
from pathlib import Path

from glshade.measure.executors import Distribution
from glshade.process import reuse_freed_memory
from glshade.sweep.run import run_sweep
from glshade.sweep.spec import spec_from_dict

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "pmd_sweep.toml"


def timed_run(spec, distribution: Distribution) -> tuple[float, Path, list]:
    out = Path(tempfile.mkdtemp(prefix="glshade_pmd_sweep_bench_"))
    start = time.perf_counter()
    result = run_sweep(spec, out, distribution)
    seconds = time.perf_counter() - start
    assert result.computed == spec.count, (result.computed, spec.count)
    return seconds, out, result.rows


def stage_seconds(out: Path) -> dict[str, float]:
    totals: dict[str, float] = {}
    for path in (out / "cases").glob("*.json"):
        for key, value in json.loads(path.read_text())["seconds"].items():
            totals[key] = totals.get(key, 0.0) + value
    return totals


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=96)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--dents", type=int, default=1)
    args = parser.parse_args()
    reuse_freed_memory()  # as `glshade sweep` does
    data = tomllib.loads(EXAMPLE.read_text())
    if args.dents > 1:
        data["grid"]["defect.dmax"] = {"start": 0.002, "stop": 0.008, "num": args.dents}
    spec = spec_from_dict(data, EXAMPLE.parent, str(EXAMPLE), size=args.size)
    print(f"pmd sweep, {spec.count} cases at {args.size}², load {os.getloadavg()[0]:.2f}")
    for repeat in range(args.repeats):
        here_s, here_out, here_rows = timed_run(spec, Distribution())
        dask_s, _, dask_rows = timed_run(spec, Distribution(workers=args.workers))
        assert dask_rows == here_rows, "the Dask table differs from the in-process one"
        print(
            f"  run {repeat + 1}: in-process {here_s:.1f} s ({spec.count / here_s:.2f} cases/s); "
            f"{args.workers} Dask workers {dask_s:.1f} s ({spec.count / dask_s:.2f} cases/s)"
        )
    stages = stage_seconds(here_out)
    print(
        "  per case (in-process): "
        + ", ".join(f"{k} {v / spec.count * 1e3:.0f} ms" for k, v in sorted(stages.items()))
    )


if __name__ == "__main__":
    main()
