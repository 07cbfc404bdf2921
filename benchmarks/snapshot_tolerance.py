"""What tolerances a snapshot test needs: how far apart two honest renders of one scene are.

A snapshot test stores an image (float, the emitter's peak = 1) and the numbers measured
of it, and later compares a new render against them. This measures, for the nine scenes
of ``benchmarks/renderer_compare.py`` (flat, cylinder, sphere at θ 85, 45, 5; 128²), one
phase-measuring (fringes) scene at 128² and one scene with a sensor at 128², the
differences between

- ``fp64``: the GL renderer in fp32 and in fp64 (``render.precision``);
- ``oracle``: the GL renderer in fp32 and the NumPy float64 oracle
  (:class:`glshade.oracle.renderer.OracleRenderer`);
- ``fp64~oracle``: the GL renderer in fp64 and the oracle (what an fp64 snapshot sees),

in the image (the largest difference in units of the emitter's peak; the pixels beyond
1e-4, 1e-3, 2e-3 and 1e-2 of it; the pixels that see the emitter in one and not the
other), and in the measured numbers: the paper's record (``Measurement.of``: its
measured columns in px) or, for the fringes, the PMD record (``PmdMeasurement.of``: its
measured columns in mm, µm and µrad), each as the record rounds it and unrounded, and
whether ``status`` matches (the closed-form columns depend on the scene alone). Where
every paper scene is ``unresolved`` at 128² (the paper's 2 mm stripes span about 3 px
per period there), the paper scenes are measured at 256² as well. The fringe scene's row
``… frames`` is its whole coded sequence (the ``frames`` output: every frame and the
white). The sensor's image is what it records (full scale 1 at 0.9 of the defect-free
peak), with noise drawn from the rendered radiance: its row ``… radiance`` is the
noiseless radiance.

    python benchmarks/snapshot_tolerance.py [--json OUT.json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from renderer_compare import SURFACES, THETAS, scenes  # this directory's nine scenes

#: Image differences counted, in units of the emitter's peak.
THRESHOLDS = (1e-4, 1e-3, 2e-3, 1e-2)
SENSOR = {"full_well_e": 10000.0, "read_noise_e": 5.0, "bit_depth": 12}
PAPER_UNITS = ("px",)
PMD_UNITS = ("mm", "µm", "µrad")


def paper_scenes(size: int):
    from glshade.scene import paper_scene

    for surface in SURFACES:
        for theta in THETAS:
            yield (
                f"{surface}_theta{theta:g}",
                paper_scene(surface, theta, 4.0, 0.005).with_size(size),
            )


def extra_scenes(size: int):
    """The fringe scene (the paper's dent, a PMD station of the default coding) and the
    sensor scene (the paper's flat plate at 45°, 12 bits, 10⁴ e⁻)."""
    from glshade.scene import paper_scene

    plate = paper_scene("flat", 45.0, 4.0, 0.005).with_size(size)
    yield "pmd_flat_theta45", plate.updated(emitter={"kind": "fringes"})
    yield "sensor_flat_theta45", plate.updated(sensor=SENSOR)


# --------------------------------------------------------------------------- images
def image_row(first: np.ndarray, second: np.ndarray, seen=None) -> dict[str, Any]:
    """The largest difference, the pixels beyond each threshold and (``seen``: the two
    masks) the pixels that see the emitter in one only."""
    difference = np.abs(first.astype(np.float64) - second.astype(np.float64))
    row: dict[str, Any] = {"max": float(difference.max()), "pixels": int(difference.size)}
    row.update({f"n>{t:g}": int((difference > t).sum()) for t in THRESHOLDS})
    if seen is not None:
        row["seen_by_one"] = int((seen[0] ^ seen[1]).sum())
    return row


def images(renderer, scene) -> dict[str, np.ndarray]:
    """What a snapshot of ``scene`` would hold: its image and mask; a fringe scene's
    coded sequence (``frames``); a sensor scene's noiseless ``radiance``."""
    frame = renderer.render(scene, ("image", "mask"))
    shot = {"": frame.image, "mask": frame.mask}
    em = scene.active.emitter
    if em.measured_by == "pmd":
        frames = (*em.sequence(scene), em.white(scene))
        shot[" frames"] = renderer.render(scene, ("frames",), frames=frames).frames
    if scene.active.records(scene):
        shot[" radiance"] = renderer.render(scene.updated(sensor={"full_well_e": None})).image
    return shot


def image_rows(first: dict[str, np.ndarray], second: dict[str, np.ndarray]) -> dict[str, Any]:
    rows = {"": image_row(first[""], second[""], (first["mask"], second["mask"]))}
    rows.update({k: image_row(v, second[k]) for k, v in first.items() if k not in ("", "mask")})
    return rows


# --------------------------------------------------------------------------- numbers
def measured(renderer, scene) -> tuple[dict[str, Any], Any]:
    """The scene's record (paper or PMD: its measured and law columns) and the result it
    was made of (its numbers unrounded)."""
    import glshade
    from glshade.instruments.record import Measurement, PmdMeasurement

    if scene.active.emitter.measured_by == "pmd":
        result = glshade.measure(scene, renderer=renderer)
        return PmdMeasurement.of(scene, result).outputs(), result
    from glshade.instruments.stripes.single import measure_scene

    result = measure_scene(renderer, scene)
    return Measurement.of(scene, result).outputs(), result


def _difference(a: Any, b: Any) -> float | None:
    """|a - b|; None where both are empty, NaN where one only is."""
    if a is None or b is None:
        return None if a is None and b is None else float("nan")
    return abs(float(a) - float(b))


def number_row(scene, first, second) -> dict[str, Any]:
    """Per column of the record in the units compared: the largest difference of the
    record's (rounded) values and, where the result has the column, of its unrounded
    ones; the two statuses."""
    from glshade.instruments.record import Measurement, PmdMeasurement

    pmd = scene.active.emitter.measured_by == "pmd"
    columns = (PmdMeasurement if pmd else Measurement).columns()
    units = PMD_UNITS if pmd else PAPER_UNITS
    (row_a, result_a), (row_b, result_b) = first, second  # (record, result) each
    row: dict[str, Any] = {"status": [row_a["status"], row_b["status"]], "raw": {}}
    for column in columns:
        if column.unit not in units or column.role != "measured":
            continue
        row[column.name] = _difference(row_a[column.name], row_b[column.name])
        if hasattr(result_a, column.name):
            raw = getattr(result_a, column.name), getattr(result_b, column.name)
            row["raw"][column.name] = _difference(*raw)
    row["values"] = [row_a, row_b]
    return row


# --------------------------------------------------------------------------- the run
#: The comparisons: (name, first source, second source).
PAIRS = (("fp64", "gl32", "gl64"), ("oracle", "gl32", "oracle"), ("fp64~oracle", "gl64", "oracle"))


def sources(gl, oracle):
    """Each source: its renderer and what it makes of a scene."""
    return {
        "gl32": (gl, lambda s: s),
        "gl64": (gl, lambda s: s.updated(render={"precision": "fp64"})),
        "oracle": (oracle, lambda s: s),
    }


def compare(result, kind: str, key: str, scene, made: dict[str, Any], rows) -> None:
    """Store each pair's comparison of what the sources ``made`` of ``scene``."""
    for label, a, b in PAIRS:
        for suffix, row in rows(scene, made[a], made[b]).items():
            result[kind][f"{key}{suffix}/{label}"] = row


def run() -> dict[str, Any]:
    from glshade.gpu.renderer import Renderer
    from glshade.oracle.renderer import OracleRenderer

    result: dict[str, Any] = {"images": {}, "numbers": {}, "seconds": {}}
    with Renderer() as gl, OracleRenderer() as oracle:
        result["renderers"] = [gl.context.info().renderer, oracle.renderer_string]
        made_by = sources(gl, oracle)
        nine = [(name, scene) for name, scene in scenes() if scene.camera.width == 128]
        at128 = nine + list(extra_scenes(128))
        seconds = result["seconds"]

        def make(what, scene, tag):
            made = {}
            for source, (renderer, variant) in made_by.items():
                start = time.perf_counter()
                made[source] = what(renderer, variant(scene))
                seconds[f"{tag}/{source}"] = seconds.get(f"{tag}/{source}", 0.0)
                seconds[f"{tag}/{source}"] += time.perf_counter() - start
            return made

        for name, scene in at128:
            made = make(images, scene, "images128")
            compare(result, "images", name, scene, made, lambda s, a, b: image_rows(a, b))
            made = make(measured, scene, "numbers128")
            compare(result, "numbers", f"{name}@128", scene, made, _number_rows)
        statuses = [
            result["numbers"][f"{name}@128/fp64"]["status"][0]
            for name, scene in at128
            if scene.active.emitter.measured_by == "paper"
        ]
        if all(status == "unresolved" for status in statuses):
            for name, scene in list(paper_scenes(256)) + [list(extra_scenes(256))[1]]:
                made = make(measured, scene, "numbers256")
                compare(result, "numbers", f"{name}@256", scene, made, _number_rows)
    return result


def _number_rows(scene, first, second) -> dict[str, Any]:
    return {"": number_row(scene, first, second)}


# --------------------------------------------------------------------------- printing
def _g(value: Any) -> str:
    if value is None:
        return "—"
    if isinstance(value, float):
        return "0" if value == 0.0 else f"{value:.2g}"
    return str(value)


def print_tables(result: dict[str, Any]) -> None:
    gl, oracle = result["renderers"]
    print(f"fp64: {gl} fp32 / fp64; oracle: {gl} fp32 / {oracle}; fp64~oracle: fp64 / oracle\n")
    print(
        "| scene / pair | max |ΔI| (peak) | " + " | ".join(f"> {t:g}" for t in THRESHOLDS), end=""
    )
    print(" | seen by one |")
    print("|---|---|" + "---|" * len(THRESHOLDS) + "---|")
    for key, row in result["images"].items():
        counts = " | ".join(str(row[f"n>{t:g}"]) for t in THRESHOLDS)
        print(f"| {key} | {row['max']:.2e} | {counts} | {_g(row.get('seen_by_one'))} |")
    for pmd in (False, True):
        rows = {k: r for k, r in result["numbers"].items() if k.startswith("pmd_") == pmd}
        if not rows:
            continue
        skip = ("status", "values", "raw")
        columns = [c for c in next(iter(rows.values())) if c not in skip]
        print("\n(record's rounded values; / unrounded where the result has them)")
        print("| case / pair | status | " + " | ".join(columns) + " |")
        print("|---|---|" + "---|" * len(columns))
        for key, row in rows.items():
            status = " / ".join(row["status"])
            cells = " | ".join(
                _g(row[c]) + (f" / {_g(row['raw'][c])}" if c in row["raw"] else "") for c in columns
            )
            print(f"| {key} | {status} | {cells} |")
    print("\nseconds: " + ", ".join(f"{k} {v:.1f}" for k, v in result["seconds"].items()))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", type=Path, help="also write the measurements here")
    args = parser.parse_args()
    start = time.perf_counter()
    result = run()
    result["seconds"]["total"] = time.perf_counter() - start
    print_tables(result)
    if args.json is not None:
        args.json.write_text(json.dumps(result, indent=1, default=str) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
