"""Render time of the optics (lens, lobes, Fresnel, sensor) at 1024² (docs/BENCHMARKS.md).

The paper's flat plate at θ 45 with its dent, image output: the pinhole mirror, the thin
lens against its aperture samples, the microfacet lobe against the integration method and
its samples (Beckmann, roughness 0.002), eq. (1) on the mirror (the Lambertian remainder),
Fresnel, and the sensor (NumPy, after read-back). Median of 5 frames after a warm-up, fp32.
Rays per second counts every ray the fragment shader traces (pixels x aperture or lobe
samples); a frame that llvmpipe needs longer than a few seconds for is still drawn in
bands (the renderer's Ctrl-C granularity), which the timing includes.

    python benchmarks/optics_render.py [--size N]
"""

from __future__ import annotations

import argparse

from freeform_render import _median_ms  # this directory's timing rule (warm-up, median)
from glshade.gpu.renderer import Renderer, frame_rays
from glshade.scene import Scene, paper_scene


def cases(size: int) -> list[tuple[str, Scene]]:
    base = paper_scene("flat", 45.0, 4.0, 0.005).with_size(size)
    out = [("pinhole, mirror", base)]
    for k in (4, 16, 64):
        out.append(
            (
                f"thin lens f/8, {k} aperture samples",
                base.updated(camera={"f_number": 8.0, "aperture_samples": k}),
            )
        )
    rough = base.updated(render={"reflection": "beckmann", "roughness": 0.002})
    out.append(("Beckmann, closed form", rough))
    for method in ("lattice", "sampling"):
        for k in (16, 64, 256):
            out.append(
                (
                    f"Beckmann, {method} {k} samples",
                    rough.updated(render={"lobe_method": method, "lobe_samples": k}),
                )
            )
    out.append(("GGX, closed form", rough.updated(render={"reflection": "ggx"})))
    out.append(
        ("mirror + eq. (1) (Lambertian remainder)", base.updated(render={"height_rms_um": 0.05}))
    )
    out.append(
        (
            "mirror + Fresnel (conductor)",
            base.updated(render={"fresnel": "conductor", "ior": 2.9, "extinction": 3.0}),
        )
    )
    out.append(("mirror + sensor (12 bit)", base.updated(sensor={})))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=1024)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    with Renderer() as renderer:
        print(f"{renderer.context.info().renderer}, {args.size}², median of {args.repeats}")
        print("| case | ms / frame | rays / frame | Mrays / s |")
        print("|---|---|---|---|")
        for label, scene in cases(args.size):
            seconds = _median_ms(renderer, scene, args.repeats) / 1e3
            rays = frame_rays(scene)
            print(
                f"| {label} | {seconds * 1e3:.0f} | {rays:.3g} | {rays / seconds / 1e6:.1f} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
