"""What writing a study's case files costs: a finished study's rows and thumbnails written
again into a fresh folder, each case on its own (``write_case``: every file flushed with
``fsync`` before its rename) and a geometry's cases as one group (``write_cases``: the
thumbnails flushed together, then the case files, which vouch for themselves), alternately;
milliseconds and ``fsync`` calls, best of ``--repeats``.

    python benchmarks/case_writes.py STUDY_DIR [--repeats 3]

``STUDY_DIR``: the ``--out`` of a finished ``glshade paper`` (its ``results.csv`` and
``cases/*.png``).
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import time
from pathlib import Path

from glshade.study import store
from glshade.study.plan import case_key


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("study", type=Path)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    rows = store.read_results_csv(args.study / "results.csv")
    thumbnails = {}
    for row in rows:
        path = args.study / "cases" / f"{case_key(*row.case)}.png"
        thumbnails[row.case] = path.read_bytes() if path.exists() else None
    groups: dict[tuple, list] = {}
    for row in rows:
        groups.setdefault(row.case[:2], []).append((row, thumbnails[row.case]))
    calls = [0]
    real_fsync = os.fsync

    def counted(fd: int) -> None:
        calls[0] += 1
        real_fsync(fd)

    os.fsync = counted
    ways = {
        "each case on its own": lambda out: [
            store.write_case(out, row, thumbnails[row.case]) for row in rows
        ],
        "a geometry's cases as one group": lambda out: [
            store.write_cases(out, group) for group in groups.values()
        ],
    }
    best: dict[str, tuple[float, int]] = {}
    for _ in range(args.repeats):
        for name, write in ways.items():
            out = Path(tempfile.mkdtemp(prefix="glshade-writes."))
            (out / "cases").mkdir()
            calls[0] = 0
            start = time.perf_counter()
            write(out)
            seconds = time.perf_counter() - start
            shutil.rmtree(out)
            if name not in best or seconds < best[name][0]:
                best[name] = (seconds, calls[0])
    print(f"{len(rows)} cases, {sum(t is not None for t in thumbnails.values())} thumbnails")
    for name, (seconds, count) in best.items():
        print(f"{name}: {1e3 * seconds:.0f} ms, {count} fsync")


if __name__ == "__main__":
    main()
