"""What a case's trace and read-back cost, and how the engine overlaps them with the
analysis (docs/BENCHMARKS.md, "Trace, read-back and overlap").

1. ``trace``: a 1024² emitter map (``measure.single.emitter_map``, 9 scenes of the paper's
   study, 3 surfaces x θ 75°/45°/15°, median of ``--repeats`` rounds): the wait for
   llvmpipe's trace, the read-back of the RG32F target and the copy of its ``v`` channel.
   Run again in subprocesses with ``LP_NUM_THREADS`` 1 and 2 (llvmpipe's threads).
2. ``gil``: how much a pure-Python thread gets done while the GL thread traces 30 maps,
   against its rate alone: with the wait releasing the interpreter lock (the renderer's
   ``GLContext.wait``) and holding it (moderngl's ``finish``, as before).
3. ``engine``: the paper's study (216 cases at ``--size``) through the engine with the
   analysis replaced by a fixed cost of ``--analysis-ms`` of NumPy work on small arrays
   (mostly under the interpreter lock, as a metric cut to the dent's region would be;
   calibrated once, alone, before the runs), or the real analysis with ``--analysis-ms 0``.
   In this process (2 analysis threads; the wait releasing or holding the lock) and on a
   LocalCluster of 2 single-threaded workers (cluster start excluded), each in a fresh
   subprocess, with ``LP_NUM_THREADS`` unset and 1. CPU seconds are the subprocess's
   (workers included); "others" is what the rest of the machine used meanwhile (this VM
   is shared: a run with others above a second or two is not a clean figure).

    python benchmarks/trace_overlap.py [--size 1024] [--repeats 5] [--analysis-ms 20]
        [--rounds 3] [--sections trace,gil,engine]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np

EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "paper_study.toml"
ENGINE_RUNS = (
    ("in-process, 2 threads, wait releases the lock", "local", None),
    ("in-process, 2 threads, wait holds the lock (before)", "local-hold", None),
    ("in-process, 2 threads, LP_NUM_THREADS=1", "local", "1"),
    ("2 Dask workers", "dask", None),
    ("2 Dask workers, LP_NUM_THREADS=1", "dask", "1"),
)


def study_scenes(size: int):
    from glshade import paper_scene

    return [
        paper_scene(surface, theta, 4.0, 0.005).with_size(size)
        for surface in ("flat", "cylinder", "sphere")
        for theta in (75, 45, 15)
    ]


def timed(stages: dict[str, list[float]], name: str, function):
    def call(*args, **kwargs):
        start = time.perf_counter()
        try:
            return function(*args, **kwargs)
        finally:
            stages[name].append(time.perf_counter() - start)

    return call


def trace_section(size: int, repeats: int) -> None:
    from glshade.gpu.renderer import Renderer

    stages: dict[str, list[float]] = {"map": [], "wait": [], "read": [], "copy": []}
    scenes = study_scenes(size)
    with Renderer() as renderer:
        for scene in scenes:  # compile the programs
            renderer.render(scene, ("uv",))
        if hasattr(renderer.context, "wait"):  # (a checkout before it waits in moderngl)
            renderer.context.wait = timed(stages, "wait", renderer.context.wait)  # type: ignore
        renderer._read = timed(stages, "read", renderer._read)  # type: ignore
        for _ in range(repeats):
            for scene in scenes:
                start = time.perf_counter()
                uv = renderer.render(scene, ("uv",)).output("uv")
                copied = time.perf_counter()
                np.ascontiguousarray(uv[..., 1])
                stages["copy"].append(time.perf_counter() - copied)
                stages["map"].append(time.perf_counter() - start)
    threads = os.environ.get("LP_NUM_THREADS", "unset")
    print(
        f"  {size}² emitter map, LP_NUM_THREADS {threads}: "
        + ", ".join(f"{k} {statistics.median(v) * 1e3:.2f} ms" for k, v in stages.items() if v)
    )


def gil_section(size: int) -> None:
    from glshade.gpu.renderer import Renderer

    scenes = study_scenes(size)[:3] * 10
    count = [0]
    stop = threading.Event()

    def spin() -> None:
        while not stop.is_set():
            count[0] += 1

    def rate(seconds: float) -> float:
        thread = threading.Thread(target=spin)
        stop.clear()
        before = count[0]
        thread.start()
        time.sleep(seconds)
        stop.set()
        thread.join()
        return (count[0] - before) / seconds

    with Renderer() as renderer:
        for scene in scenes[:3]:
            renderer.render(scene, ("uv",))
        releasing = renderer.context.wait
        for label, wait in (("releases", releasing), ("holds", renderer.context.gl.finish)):
            renderer.context.wait = wait  # type: ignore[method-assign]
            alone = rate(1.0)
            thread = threading.Thread(target=spin)
            stop.clear()
            thread.start()
            time.sleep(0.1)
            before, start = count[0], time.perf_counter()
            for scene in scenes:
                renderer.render(scene, ("uv",))
            seconds = time.perf_counter() - start
            done = count[0] - before
            stop.set()
            thread.join()
            print(
                f"  wait {label} the lock: {seconds / len(scenes) * 1e3:.1f} ms a map beside a "
                f"busy Python thread, which ran at {100 * done / seconds / alone:.0f} % of its "
                "rate alone"
            )


# ------------------------------------------------------------------ the engine
def synthetic_work(v1: np.ndarray, repeats: int) -> float:
    """NumPy calls on a 96² cut of the map: short ones, mostly under the lock."""
    rows, cols = v1.shape
    cut = v1[rows // 2 - 96 : rows // 2 + 96 : 2, cols // 2 - 96 : cols // 2 + 96 : 2]
    total = 0.0
    for _ in range(repeats):
        total += float(np.abs(np.diff(np.nan_to_num(cut), axis=0)).sum())
    return total


def calibrated_repeats(v1: np.ndarray, milliseconds: float) -> int:
    repeats = 16
    while True:
        start = time.perf_counter()
        synthetic_work(v1, repeats)
        seconds = time.perf_counter() - start
        if seconds > 0.25:
            return max(1, round(repeats * milliseconds / 1e3 / seconds))
        repeats *= 2


def install_synthetic(repeats: int, template) -> None:
    """Replace the engine's per-case analysis by ``repeats`` of :func:`synthetic_work`."""
    from glshade.measure import engine

    def analyse(case, baseline, v1, trace_s, extra):
        synthetic_work(v1, repeats)
        return engine.Measured(case, template, trace_s, None)

    engine._analyse = analyse  # type: ignore[assignment]


def dask_task(batch, settings, repeats: int, template):
    """A Dask task: the worker's engine with the synthetic analysis (when asked)."""
    from glshade.measure.cluster import measure_batch

    if repeats:
        install_synthetic(repeats, template)
    return measure_batch(batch, settings, False)


def warm(renderer, cases) -> None:
    """Compile the programs of ``cases`` (with and without the dent) on ``renderer``."""
    from glshade.instruments.stripes.single import emitter_map

    for case in cases:
        emitter_map(renderer, case.scene)
        emitter_map(renderer, case.scene.without_defect())


def warm_worker(cases) -> None:
    from distributed import get_worker

    from glshade.measure.cluster import PLUGIN_NAME

    warm(get_worker().plugins[PLUGIN_NAME].get(), cases)  # type: ignore[attr-defined]


def engine_run(kind: str, size: int, work: int) -> None:
    """One configuration, in this (fresh) process, its programs compiled first (on each
    worker), the analysis ``work`` repeats of :func:`synthetic_work` (0: the real one):
    prints ``cases seconds``."""
    from distributed import as_completed

    from glshade.gpu.renderer import Renderer
    from glshade.instruments.stripes.single import measure_scene
    from glshade.measure.cluster import DaskExecutor, batches
    from glshade.measure.executors import Distribution, LocalExecutor
    from glshade.process import reuse_freed_memory
    from glshade.sweep.spec import load_spec

    reuse_freed_memory()
    spec = load_spec(EXAMPLE, size=size)
    cases = [point.case for point in spec.cases()]
    firsts = list({case.scene.surface: case for case in cases}.values())
    with Renderer() as renderer:
        template = measure_scene(renderer, cases[0].scene, spec.settings)
        if work:
            install_synthetic(work, template)
        if kind == "dask":
            with DaskExecutor(Distribution(workers=2)) as executor:
                client = executor.client
                workers = list(client.scheduler_info()["workers"])
                for address in workers:
                    client.submit(warm_worker, firsts, workers=[address], pure=False).result()
                start = time.perf_counter()
                futures = [
                    client.submit(dask_task, batch, spec.settings, work, template, pure=False)
                    for batch in batches(cases, 16)  # a paper sweep
                ]
                count = sum(len(f.result()) for f in as_completed(futures, loop=client.loop))
                seconds = time.perf_counter() - start
        else:
            if kind == "local-hold":
                renderer.context.wait = renderer.context.gl.finish  # type: ignore[method-assign]
            warm(renderer, firsts)
            with LocalExecutor(threads=2, renderer=renderer) as executor:
                start = time.perf_counter()
                count = len(list(executor.rows(cases, spec.settings, False)))
                seconds = time.perf_counter() - start
    print(count, seconds)


def busy_seconds() -> float:
    fields = Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]
    return sum(int(fields[i]) for i in (0, 1, 2, 5, 6)) / os.sysconf("SC_CLK_TCK")


def children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def synthetic_repeats(size: int, milliseconds: float) -> int:
    """Repeats of :func:`synthetic_work` that take ``milliseconds`` here, alone, on the
    study's first map."""
    from glshade.gpu.renderer import Renderer
    from glshade.instruments.stripes.single import emitter_map
    from glshade.sweep.spec import load_spec

    scene = load_spec(EXAMPLE, size=size).cases()[0].case.scene
    with Renderer() as renderer:
        v1 = emitter_map(renderer, scene)
    return calibrated_repeats(v1, milliseconds)


def engine_section(size: int, milliseconds: float, rounds: int) -> None:
    work = synthetic_repeats(size, milliseconds) if milliseconds > 0 else 0
    analysis = f"a {milliseconds:g} ms analysis" if work else "the real analysis"
    print(f"  the paper's study at {size}², {analysis}, {rounds} rounds (median):")
    speeds: dict[str, list[float]] = {label: [] for label, _, _ in ENGINE_RUNS}
    for _ in range(rounds):
        for label, kind, threads in ENGINE_RUNS:
            env = dict(os.environ)
            env.pop("LP_NUM_THREADS", None)
            if threads is not None:
                env["LP_NUM_THREADS"] = threads
            busy, cpu = busy_seconds(), children_cpu()
            command = [sys.executable, __file__, "--engine-run", kind, "--size", str(size)]
            command += ["--work", str(work)]
            out = subprocess.run(command, env=env, capture_output=True, text=True, check=True)
            count, seconds = out.stdout.split()[-2:]
            used = children_cpu() - cpu
            others = max(0.0, busy_seconds() - busy - used)
            speeds[label].append(int(count) / float(seconds))
            print(
                f"    {label}: {speeds[label][-1]:.1f} cases/s ({float(seconds):.1f} s; "
                f"CPU {used:.1f} s with start-up; others {others:.1f} s)"
            )
    for label, values in speeds.items():
        print(f"  {label}: median {statistics.median(values):.1f} cases/s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--analysis-ms", type=float, default=20.0)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--sections", default="trace,gil,engine")
    parser.add_argument("--engine-run", help=argparse.SUPPRESS)
    parser.add_argument("--work", type=int, default=0, help=argparse.SUPPRESS)
    parser.add_argument("--trace-only", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.engine_run:
        engine_run(args.engine_run, args.size, args.work)
        return
    if args.trace_only:
        trace_section(args.size, args.repeats)
        return
    sections = args.sections.split(",")
    if "trace" in sections:
        print("trace and read-back:")
        for threads in ("1", "2"):
            env = {**os.environ, "LP_NUM_THREADS": threads}
            command = [sys.executable, __file__, "--trace-only", "--size", str(args.size)]
            command += ["--repeats", str(args.repeats)]
            subprocess.run(command, env=env, check=True)
    if "gil" in sections:
        print("the interpreter lock during the wait:")
        gil_section(args.size)
    if "engine" in sections:
        print("the engine:")
        engine_section(args.size, args.analysis_ms, args.rounds)


if __name__ == "__main__":
    main()
