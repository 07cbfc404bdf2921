"""What two OpenGL drivers make of the same scenes: images, uv maps and measured numbers
saved on each, compared here (docs/BENCHMARKS.md, "llvmpipe against an NVIDIA driver").

    python benchmarks/renderer_compare.py save OUT.npz      # on each machine
    python benchmarks/renderer_compare.py compare A.npz B.npz

``save`` renders the snapshot tests' nine scenes (flat, cylinder, sphere at θ 85, 45, 5;
128²) and the paper's default scene at 512², each in fp32 and fp64 (image and uv map),
and measures the nine at 256² (the paper's metric and its continuous limit); it stores
the GL renderer string beside them. ``compare`` prints, per scene and precision, the
largest image difference in units of the emitter's peak, the number of pixels beyond
1e-3 and 1e-2 of it, the largest uv difference (mm on the emitter) where both see it,
the pixels that see the emitter in one and not the other, and the measured numbers side
by side.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

SURFACES = ("flat", "cylinder", "sphere")
THETAS = (85.0, 45.0, 5.0)


def scenes():
    from glshade.scene import paper_scene

    for surface in SURFACES:
        for theta in THETAS:
            yield (
                f"{surface}_theta{theta:g}",
                paper_scene(surface, theta, 4.0, 0.005).with_size(128),
            )
    yield "paper_default_512", paper_scene("flat", 45.0, 4.0, 0.005).with_size(512)


def save(path: Path) -> None:
    from glshade.gpu.renderer import Renderer
    from glshade.instruments.record import Measurement
    from glshade.instruments.stripes.single import measure_scene
    from glshade.scene import paper_scene

    arrays: dict[str, np.ndarray] = {}
    numbers: dict[str, dict] = {}
    with Renderer() as renderer:
        info = renderer.context.info()
        for name, scene in scenes():
            for precision in ("fp32", "fp64"):
                frame = renderer.render(
                    scene.updated(render={"precision": precision}), ("image", "uv")
                )
                arrays[f"{name}/{precision}/image"] = frame.output("image").astype(np.float32)
                arrays[f"{name}/{precision}/uv"] = frame.output("uv").astype(np.float32)
        for surface in SURFACES:
            for theta in THETAS:
                scene = paper_scene(surface, theta, 4.0, 0.005).with_size(256)
                record = Measurement.of(scene, measure_scene(renderer, scene))
                numbers[f"{surface}_theta{theta:g}"] = record.outputs()
    meta = {"renderer": info.renderer, "version": info.version, "numbers": numbers}
    np.savez_compressed(path, meta=np.array(json.dumps(meta, default=str)), **arrays)
    print(f"wrote {path}: {len(arrays)} arrays, renderer {info.renderer}")


def compare(first: Path, second: Path) -> None:
    a, b = np.load(first), np.load(second)
    meta_a, meta_b = (json.loads(str(f["meta"])) for f in (a, b))
    print(f"A: {meta_a['renderer']}\nB: {meta_b['renderer']}\n")
    print(
        "| scene | precision | max |ΔI| (peak) | px > 1e-3 | px > 1e-2 | max |Δv| mm "
        "| seen by one |"
    )
    print("|---|---|---|---|---|---|---|")
    for key in sorted(k for k in a.files if k.endswith("/image")):
        name, precision, _ = key.split("/")
        image = np.abs(a[key] - b[key])
        uv_a, uv_b = a[f"{name}/{precision}/uv"], b[f"{name}/{precision}/uv"]
        seen_a, seen_b = np.isfinite(uv_a[..., 1]), np.isfinite(uv_b[..., 1])
        both = seen_a & seen_b
        dv = np.abs(uv_a[..., 1] - uv_b[..., 1])[both]
        print(
            f"| {name} | {precision} | {image.max():.2e} | {(image > 1e-3).sum()} | "
            f"{(image > 1e-2).sum()} | {dv.max() if dv.size else float('nan'):.2e} | "
            f"{int((seen_a ^ seen_b).sum())} |"
        )
    print("\n| case | visibility_px A / B | continuous A / B | deflection A / B | status A / B |")
    print("|---|---|---|---|---|")
    for case, numbers in meta_a["numbers"].items():
        other = meta_b["numbers"][case]
        limit = numbers["visibility_continuous_px"], other["visibility_continuous_px"]
        print(
            f"| {case} | {numbers['visibility_px']:g} / {other['visibility_px']:g} | "
            f"{limit[0]:.4f} / {limit[1]:.4f} | "
            f"{numbers['deflection_px']:.4f} / {other['deflection_px']:.4f} | "
            f"{numbers['status']} / {other['status']} |"
        )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="verb", required=True)
    sub.add_parser("save").add_argument("out", type=Path)
    both = sub.add_parser("compare")
    both.add_argument("first", type=Path)
    both.add_argument("second", type=Path)
    args = parser.parse_args()
    if args.verb == "save":
        save(args.out)
    else:
        compare(args.first, args.second)
    return 0


if __name__ == "__main__":
    sys.exit(main())
