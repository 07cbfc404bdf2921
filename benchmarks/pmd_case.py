"""What one phase-measuring case costs (docs/BENCHMARKS.md, "Phase measuring").

1. The sequence render: the default coding's 32 frames and the screen's white shaded from
   one trace (the ``frames`` output), against the same 33 frames rendered one by one (an
   image each): frames per second both ways, for the paper's dented flat plate and sphere,
   pinhole and 2 x 2 supersampling; and on the flat plate through each reflection model
   (every frame shaded through the finish's lobe, eq. (1)'s diffuse part).
2. One whole case (``measure_pmd_scene``, its defect-free analysis included) through a
   10 000 e- sensor: the seconds of each stage.

Median of ``--repeats`` after a warm-up, fp32.

    python benchmarks/pmd_case.py [--size N] [--repeats K] [--stages | --agreement]
"""

from __future__ import annotations

import argparse
import statistics
import time

from glshade.gpu.renderer import Renderer
from glshade.instruments.pmd.baseline import pmd_baseline
from glshade.instruments.pmd.model import station_model
from glshade.instruments.pmd.settings import PmdSettings
from glshade.instruments.pmd.station import measure_pmd_scene
from glshade.scene import Scene, paper_scene


def station(surface: str, size: int, supersample: int = 1) -> Scene:
    scene = paper_scene(surface, 45.0, 4.0, 0.005).with_size(size)
    periods = [2.0, 16.0, 128.0, 1024.0] if surface == "flat" else [10.0, 80.0, 640.0]
    return scene.updated(
        emitter={"kind": "fringes", "periods": periods}, render={"supersample": supersample}
    )


#: The finishes the sequence is shaded through (render table values).
FINISHES = {
    "mirror": {},
    "blinn-phong (closed)": {"reflection": "blinn-phong", "shininess": 2e6},
    "beckmann (closed)": {"reflection": "beckmann", "roughness": 1e-3},
    "ggx (closed)": {"reflection": "ggx", "roughness": 1e-3},
    "ggx (lattice, 64 samples)": {"reflection": "ggx", "roughness": 1e-3, "lobe_method": "lattice"},
    "mirror with eq. (1)": {"height_rms_um": 0.03},
}


def median_s(action, repeats: int) -> float:
    action()  # warm-up: compile, allocate
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        action()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def sequence_rates(renderer: Renderer, scene: Scene, repeats: int) -> tuple[float, float]:
    """Frames per second: the stack in one trace, and frame by frame."""
    emitter = scene.active.emitter
    frames = (*emitter.sequence(scene), emitter.white(scene))
    stacked = median_s(lambda: renderer.render(scene, ("frames",), frames=frames), repeats)
    shown = [emitter.showing(scene, frame) for frame in frames]

    def one_by_one() -> None:
        for each in shown:
            renderer.render(each, ("image",))

    single = median_s(one_by_one, max(1, repeats // 2))
    return len(frames) / stacked, len(frames) / single


def case_stages(renderer: Renderer, scene: Scene) -> dict[str, float]:
    scene = scene.updated(sensor={"full_well_e": 10000.0})
    measure_pmd_scene(renderer, scene.with_size(64))  # warm-up
    start = time.perf_counter()
    baseline = pmd_baseline(renderer, station_model(scene), PmdSettings())
    _ = baseline.slopes  # the defect-free slope map, worked out once
    base_s = time.perf_counter() - start
    start = time.perf_counter()
    result = measure_pmd_scene(renderer, scene, PmdSettings(), baseline)
    case_s = time.perf_counter() - start
    traced = result.maps.traced
    share = 1.0 if traced is None else traced.rows * traced.cols / scene.camera.width**2
    return {
        "defect-free analysis (trace, record, decode, nominal geometry, slopes)": base_s,
        f"dent: trace ({share:.0%} of the image)": result.seconds["render"],
        "dent: record and decode": result.seconds["decode"],
        "dent: the noise twin over its window": result.seconds["twin"],
        "dent: slopes, heights, fit": result.seconds["heights"],
        "dent: the whole case, given the defect-free analysis": case_s,
        "whole case, the defect-free analysis included": base_s + case_s,
    }


def decode_agreement(renderer: Renderer, size: int) -> None:
    """The GPU's decoded screen points against the NumPy decoder's on the same noiseless
    sequence: the largest difference (mm) and whether the same pixels are valid."""
    import numpy as np

    from glshade.instruments.pmd.shots import shoot

    for surface in ("flat", "sphere"):
        scene = station(surface, size)
        coding = station_model(scene).coding
        ref = shoot(renderer, scene, coding, PmdSettings(), gpu=False).decoding
        gpu = shoot(renderer, scene, coding, PmdSettings(), gpu=True).decoding
        worst = float(np.nanmax(np.abs(ref.uv - gpu.uv)))
        same = bool(np.array_equal(ref.valid, gpu.valid))
        print(f"| {surface}, {size}² | {worst:.2e} mm | {same} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--stages", action="store_true", help="the case's stages alone")
    parser.add_argument(
        "--agreement", action="store_true", help="the GPU decode against NumPy's alone"
    )
    args = parser.parse_args()
    with Renderer() as renderer:
        print(f"{renderer.context.info().renderer}, {args.size}²")
        if args.agreement:
            print("| scene | largest decoded difference | same valid pixels |")
            print("|---|---|---|")
            decode_agreement(renderer, args.size)
            return
        if args.stages:
            for surface in ("flat", "sphere"):
                print(f"| stage ({surface}, 10 000 e- sensor) | s |")
                print("|---|---|")
                for stage, seconds in case_stages(renderer, station(surface, args.size)).items():
                    print(f"| {stage} | {seconds:.2f} |")
            return
        print("| scene | frames/s, one trace | frames/s, frame by frame | ratio |")
        print("|---|---|---|---|")
        for surface in ("flat", "sphere"):
            for supersample in (1, 2):
                scene = station(surface, args.size, supersample)
                stacked, single = sequence_rates(renderer, scene, args.repeats)
                label = f"{surface}, dent, {supersample}² rays/px"
                print(f"| {label} | {stacked:.1f} | {single:.1f} | {stacked / single:.1f} |")
        print()
        print("| finish (flat, 1 ray/px) | frames/s, one trace | frames/s, frame by frame |")
        print("|---|---|---|")
        for name, values in FINISHES.items():
            scene = station("flat", args.size).updated(render=values)
            stacked, single = sequence_rates(renderer, scene, args.repeats)
            print(f"| {name} | {stacked:.1f} | {single:.1f} |")
        print()
        print("| stage (flat, 10 000 e- sensor) | s |")
        print("|---|---|")
        for stage, seconds in case_stages(renderer, station("flat", args.size)).items():
            print(f"| {stage} | {seconds:.2f} |")


if __name__ == "__main__":
    main()
