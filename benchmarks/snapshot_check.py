"""What one snapshot check costs: rendering and measuring a scene as the pytest plugin
does (``glshade.snapshot.station``), on the GL renderer and on the NumPy oracle that stands
in where no OpenGL context can be made (docs/BENCHMARKS.md, "Snapshot checks").

    python benchmarks/snapshot_check.py

GL: the first check of each scene on one renderer (its programs compiled then) and the
second.
Oracle: the first check on a fresh one (it keeps traced rays between the metric's phases,
and would keep them between two checks of one scene too).
"""

from __future__ import annotations

import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def scenes():
    import glshade
    from glshade.scene import paper_scene

    return {
        "paper's flat plate, 128²": paper_scene("flat", 45.0, 4.0, 0.005).with_size(128),
        "door panel (height map), 160²": glshade.Scene.load(
            ROOT / "examples/snapshot_testing/door_panel.toml"
        ),
        "PMD station, 128²": glshade.Scene.load(ROOT / "examples/pmd_station.toml").with_size(128),
    }


def seconds(station, scene) -> float:
    start = time.perf_counter()
    station.shoot(scene)
    return time.perf_counter() - start


def main() -> None:
    from glshade.snapshot.station import open_station

    start = time.perf_counter()
    gl = open_station("gl")
    print(f"renderer: {gl.identity} (opened in {time.perf_counter() - start:.2f} s)")
    print(f"{'scene':32s} {'GL first s':>10s} {'GL s':>7s} {'oracle s':>9s}")
    try:
        for name, scene in scenes().items():
            first = seconds(gl, scene)
            on_gl = seconds(gl, scene)
            oracle = open_station("oracle")
            try:
                on_oracle = seconds(oracle, scene)
            finally:
                oracle.release()
            print(f"{name:32s} {first:10.2f} {on_gl:7.2f} {on_oracle:9.2f}")
    finally:
        gl.release()


if __name__ == "__main__":
    main()
