"""Cases per second of sweeps, in-process against Dask (docs/BENCHMARKS.md).

1. The paper's study (``examples/paper_study.toml``, 216 cases) at ``--size`` pixels:
   in this process (2 analysis threads) and on a LocalCluster of ``--workers`` single-
   threaded worker processes (one task per geometry, 8 cases). Each run starts from an
   empty output directory; the Dask time includes starting the cluster.
2. The Dask path's overhead per case: 256 tiny cases (32²) on warm executors (context
   made, program compiled), in this process with one thread and on one local worker with
   at most 1 and 16 cases per task: θ from 5° to 85° (every case its own geometry, so
   one case per task whatever the batch), and dmax from 1 to 10 µm (one geometry: a task
   of 16 shares its defect-free analysis, one of 1 makes its own). The difference per
   case is what the Dask path costs (scheduling, pickling the scene, returning the row,
   and with one case per task the baseline each task makes again).
3. Where the time of a case goes (trace on GL, analysis on the CPU), from the case files.

    python benchmarks/sweep_throughput.py [--size 256] [--workers 2]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

from glshade.measure.cluster import DaskExecutor
from glshade.measure.executors import Distribution, LocalExecutor
from glshade.process import reuse_freed_memory
from glshade.sweep.run import run_sweep
from glshade.sweep.spec import load_spec, spec_from_dict

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "paper_study.toml"


def timed_run(spec, distribution: Distribution) -> tuple[float, Path]:
    out = Path(tempfile.mkdtemp(prefix="glshade_sweep_bench_"))
    start = time.perf_counter()
    result = run_sweep(spec, out, distribution)
    seconds = time.perf_counter() - start
    assert result.computed == spec.count, (result.computed, spec.count)
    return seconds, out


def stage_seconds(out: Path) -> dict[str, float]:
    totals: dict[str, float] = {}
    for path in (out / "cases").glob("*.json"):
        for key, value in json.loads(path.read_text())["seconds"].items():
            totals[key] = totals.get(key, 0.0) + value
    return totals


def cluster_start_seconds(workers: int) -> float:
    start = time.perf_counter()
    with DaskExecutor(Distribution(workers=workers)):
        seconds = time.perf_counter() - start
    return seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=256)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    reuse_freed_memory()  # as `glshade sweep` does (the workers' plugin does it in theirs)

    spec = load_spec(EXAMPLE, size=args.size)
    print(f"paper study, {spec.count} cases at {args.size}²")
    here_s, here_out = timed_run(spec, Distribution(threads=2))
    stages = stage_seconds(here_out)
    print(f"  in-process (2 threads): {here_s:.1f} s, {spec.count / here_s:.2f} cases/s")
    print(
        "  per case: "
        + ", ".join(f"{k} {v / spec.count * 1e3:.0f} ms" for k, v in sorted(stages.items()))
    )
    dask_s, _ = timed_run(spec, Distribution(workers=args.workers, batch=8))
    print(
        f"  {args.workers} Dask workers: {dask_s:.1f} s, {spec.count / dask_s:.2f} cases/s "
        f"(cluster start {cluster_start_seconds(args.workers):.1f} s of it)"
    )

    for axis, grid in (
        (
            "θ 5°…85°: every case its own geometry",
            {"camera.theta_deg": {"start": 5.0, "stop": 85.0, "num": 256}},
        ),
        ("dmax 1…10 µm: one geometry", {"defect.dmax": {"start": 0.001, "stop": 0.01, "num": 256}}),
    ):
        tiny = spec_from_dict({"size": 32, "grid": grid})
        cases = [point.case for point in tiny.cases()]  # made before the clock starts
        local = per_case_seconds(LocalExecutor(threads=1), cases, tiny)
        line = [
            f"tiny cases (32², 256 of {axis}), warm executors: in-process {local * 1e3:.1f} ms/case"
        ]
        for batch in (1, 16):
            with DaskExecutor(Distribution(workers=1, batch=batch)) as executor:
                dask = per_case_seconds(executor, cases, tiny)
            line.append(
                f"one Dask worker, at most {batch} case(s) per task: {dask * 1e3:.1f} ms/case "
                f"({(dask - local) * 1e3:+.1f} ms/case)"
            )
        print("\n  ".join(line))


def per_case_seconds(executor, cases, spec) -> float:
    """Seconds per case on a warm executor (its context made and program compiled)."""
    with executor:
        list(executor.rows(cases[:4], spec.settings, False))
        start = time.perf_counter()
        rows = list(executor.rows(cases, spec.settings, False))
        seconds = time.perf_counter() - start
    assert len(rows) == len(cases)
    return seconds / len(cases)


if __name__ == "__main__":
    main()
