"""What the sensor's black level changes in a PMD station's recording and decoding
(docs/pmd.md, "Choices beyond the scene conventions").

    python benchmarks/pmd_black_level.py [--size 256] [--seeds 4] [--full-well 10000]

The paper's scene (flat, θ 45°, the 5 µm dent) under the default fringe coding, through a
sensor of 5 e- read noise and 12 bits, without a black level (``sensor.black_level_dn =
0``: read noise below 0 DN is clipped) and with the default (``"auto"``: 64 DN), over
several seeds: the share of the recorded pixel-frames that read exactly 0 (the clipped
ones), ``pmd_noise_mm`` against ``pmd_noise_predicted_mm`` and their ratio, and the mean
ratio over the seeds.
"""

from __future__ import annotations

import argparse

import numpy as np


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=256, help="pixels across (default 256)")
    parser.add_argument("--seeds", type=int, default=4, help="noise seeds (default 4)")
    parser.add_argument("--full-well", type=float, default=10000.0, help="electrons")
    args = parser.parse_args()

    from glshade.gpu.renderer import Renderer
    from glshade.instruments.pmd.station import measure_pmd_scene
    from glshade.measure.single import as_method
    from glshade.scene import paper_scene

    base = as_method(paper_scene().with_size(args.size), "pmd")
    print("| black level | seed | exact-0 pixel-frames | pmd_noise_mm | predicted | ratio |")
    print("|---|---:|---:|---:|---:|---:|")
    with Renderer() as renderer:
        for black in (0, "auto"):
            ratios = []
            for seed in range(args.seeds):
                sensor = {"full_well_e": args.full_well, "black_level_dn": black, "seed": seed}
                scene = base.updated(sensor=sensor)
                result = measure_pmd_scene(renderer, scene)
                zeros = float(np.mean(result.maps.recorded == 0.0))
                ratio = result.pmd_noise_mm / result.pmd_noise_predicted_mm
                ratios.append(ratio)
                print(
                    f"| {black} ({scene.sensor.black_dn} DN) | {seed} | {zeros:.2%} | "
                    f"{result.pmd_noise_mm:.4e} | {result.pmd_noise_predicted_mm:.4e} | "
                    f"{ratio:.4f} |"
                )
            print(f"| {black}: mean ratio | | | | | {np.mean(ratios):.4f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
