"""``glshade render``: one image of a scene (and its uv map)."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from glshade.app.args import (
    add_scene_flags,
    check_outputs,
    path_arg,
    save_scene,
    scene_from_args,
    warn,
)
from glshade.files import atomic_write_bytes
from glshade.oracle.advice import scene_warnings

SCENE_FORMAT = "docs/scene-format.md"


def add(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "render",
        help="render one image (and its uv map)",
        description=f"Render a scene: a TOML scene file ({SCENE_FORMAT}: every key, unit, default "
        "and range) "
        "or, without one, the paper's scene (flat, theta 45, sigma2 4 mm², dmax 5 µm, 1024²). "
        "Flags override "
        "the file; lengths are in mm unless they carry a unit (--dmax 5um).",
    )
    add_scene_flags(p)
    p.add_argument(
        "-o",
        "--output",
        type=path_arg,
        default=Path("render.png"),
        help="image, PNG or TIFF by its extension (default %(default)s); lossy formats are refused",
    )
    p.add_argument(
        "--bits",
        type=int,
        choices=(8, 16, 32),
        default=8,
        help="bits per pixel: 8 or 16 (integers), 32 (float radiance, TIFF only); default 8",
    )
    p.add_argument(
        "--uv",
        type=path_arg,
        metavar="UV.npy",
        help="also write the uv map (float32 H×W×2, mm, NaN = no hit)",
    )


def run(args: argparse.Namespace) -> int:
    from glshade.files import check_image_output, encode_image, write_npy
    from glshade.frame import exposure_gain
    from glshade.gpu.context import GLContext
    from glshade.gpu.renderer import Renderer

    scene = scene_from_args(args)
    image_path = check_image_output(args.output, "-o", args.bits)
    uv = [("--uv", args.uv, (".npy",))] if args.uv is not None else []
    check_outputs(args, scene, [("-o", args.output, ()), *uv])
    warn(scene_warnings(scene))
    outputs = ("image", "uv") if args.uv is not None else ("image",)
    with (
        GLContext(device_index=args.device) as context,
        Renderer(context, progress=True) as renderer,
    ):
        start = time.perf_counter()
        frame = renderer.render(scene, outputs)
        seconds = time.perf_counter() - start
    image = frame.output("image")
    if not scene.active.records(scene):  # a sensor's image is already in recorded units
        image = image * exposure_gain(scene.camera.exposure, image)
    atomic_write_bytes(args.output, encode_image(image, image_path.suffix, args.bits), "-o")
    if args.uv is not None:
        write_npy(args.uv, frame.output("uv"))
    save_scene(args, scene)
    cam = scene.camera
    print(
        f"wrote {args.output} ({cam.width}x{cam.height}, {scene.surface.kind}, theta "
        f"{cam.theta_deg:g} deg, "
        f"{scene.render.precision}, {seconds * 1e3:.0f} ms)"
    )
    return 0
