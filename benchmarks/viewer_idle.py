"""CPU the interactive viewer burns while nobody touches it. docs/BENCHMARKS.md, "The
viewer at rest".

Opens ``glshade view`` (the paper's scene, panel drawn) under Xvfb, waits for it to
settle (the first trace, the metrics), then reads the CPU time of the viewer's process
(all its threads) and of the X server over a quiet stretch, from /proc through psutil.

    python benchmarks/viewer_idle.py [--seconds 10] [--settle 8] [--size 512]
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import time

import psutil


def _cpu(process: psutil.Process) -> float:
    times = process.cpu_times()
    return times.user + times.system


def _find(parent: psutil.Process, wanted, timeout_s: float = 30.0) -> psutil.Process:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for child in parent.children(recursive=True):
            try:
                if wanted(child.cmdline()):
                    return child
            except (psutil.NoSuchProcess, psutil.ZombieProcess):
                continue
        time.sleep(0.1)
    raise RuntimeError("the viewer did not start")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="quiet stretch measured")
    parser.add_argument("--settle", type=float, default=8.0, help="seconds before measuring")
    parser.add_argument("--size", type=int, default=512)
    args = parser.parse_args()
    if shutil.which("xvfb-run") is None:
        sys.exit("needs xvfb-run (Debian package xvfb)")
    command = [
        "xvfb-run",
        "-a",
        "-s",
        "-screen 0 1280x1024x24",
        sys.executable,
        "-m",
        "glshade",
        "view",
        "--size",
        str(args.size),
    ]
    runner = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    viewer = None
    try:
        parent = psutil.Process(runner.pid)
        viewer = _find(parent, lambda cmd: cmd[:4] == [sys.executable, "-m", "glshade", "view"])
        server = _find(parent, lambda cmd: bool(cmd) and cmd[0].endswith("Xvfb"))
        time.sleep(args.settle)
        if runner.poll() is not None:
            raise RuntimeError(runner.stderr.read().decode() if runner.stderr else "exited")
        start = time.perf_counter()
        cpu_viewer, cpu_server = _cpu(viewer), _cpu(server)
        time.sleep(args.seconds)
        wall = time.perf_counter() - start
        cpu_viewer, cpu_server = _cpu(viewer) - cpu_viewer, _cpu(server) - cpu_server
    finally:
        if viewer is not None and viewer.is_running():
            viewer.terminate()  # xvfb-run then ends its X server
        else:
            runner.terminate()
        runner.wait(timeout=30)
    print(
        f"idle viewer at {args.size}²: {100 * cpu_viewer / wall:.1f} % of a core "
        f"({cpu_viewer:.2f} s CPU over {wall:.1f} s); Xvfb: {100 * cpu_server / wall:.1f} %"
    )


if __name__ == "__main__":
    main()
