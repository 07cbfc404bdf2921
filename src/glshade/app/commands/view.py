"""``glshade view``: the interactive viewer (the viewer extra), or a scripted run of it."""

from __future__ import annotations

import argparse

from glshade.app.args import SIZE_HELP, add_save_scene, check_outputs, path_arg, save_scene, warn
from glshade.errors import GlshadeError
from glshade.oracle.advice import scene_warnings
from glshade.scene import Scene, paper_scene

#: The viewer's pixels across without ``--size``.
VIEW_SIZE = 512


def add(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "view",
        help="open the interactive viewer (needs the viewer extra)",
        description="Open a window that renders the scene with the batch renderer's shaders, with "
        "a control "
        "panel, views (image, defect-free, contour overlay, displacement, and the maps of a "
        "phase-measuring station: pmd-phase, pmd-modulation, pmd-error, pmd-slope) and live "
        "readouts. "
        "Keys: S screenshot, T save the scene as TOML, R reset to the paper's defaults, O toggle "
        "the overlay, P toggle the PMD phase view. "
        "Scripted mode: --frames N [--screenshot out.png] [--set theta=5 ...].",
    )
    p.add_argument(
        "scene", nargs="?", type=path_arg, help="scene file (TOML); default: the paper's scene"
    )
    p.add_argument(
        "--size",
        type=int,
        metavar="N",
        help=f"{SIZE_HELP} (default {VIEW_SIZE}, unless --set camera.width is given)",
    )
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a setting by its short name or dotted path, as render's --set: theta=5, "
        "sigma2=9, surface=sphere, camera.distance=200; and the viewer's own: view=overlay, "
        "animate=1, view=pmd-phase, pmd_size=256 (the PMD views' pixels across), concave=1 "
        "(repeatable)",
    )
    p.add_argument("--frames", type=int, metavar="N", help="draw N frames, then exit")
    p.add_argument(
        "--screenshot", type=path_arg, metavar="PNG", help="with --frames: save the last frame"
    )
    p.add_argument(
        "--benchmark",
        choices=("phase", "theta"),
        help="with --frames: animate the phase or drag theta, print fps",
    )
    p.add_argument(
        "--no-panel", action="store_true", help="no control panel (the window shows the image only)"
    )
    add_save_scene(p)


def run(args: argparse.Namespace) -> int:
    from glshade.app import viewer

    scene = Scene.load(args.scene) if args.scene is not None else paper_scene()
    table = None
    if args.scene is not None:  # how the file says its scene is measured: the views' settings
        from glshade.instruments.table import file_measure_table

        table = file_measure_table(args.scene, scene.active.emitter.measured_by)
    scene, extra = viewer.parse_sets(args.set, scene, args.size, default_size=VIEW_SIZE)
    if args.frames is not None and args.frames < 1:
        raise GlshadeError(f"--frames: must be an integer >= 1, got {args.frames}")
    if (args.screenshot is not None or args.benchmark) and args.frames is None:
        raise GlshadeError("--screenshot and --benchmark need --frames N")
    screenshot = [("--screenshot", args.screenshot, (".png",))] if args.screenshot else []
    check_outputs(args, scene, screenshot)
    warn(scene_warnings(scene))
    save_scene(args, scene)  # the scene the window opens with (T saves it as it is then)
    options = viewer.ViewerOptions(
        scene=scene,
        view=extra.get("view", "image"),
        animate=args.benchmark == "phase"
        or extra.get("animate", "0").lower() in ("1", "true", "yes"),
        frames=args.frames,
        screenshot=args.screenshot,
        benchmark=args.benchmark,
        panel=not args.no_panel,
        pmd_size=int(extra["pmd_size"]) if "pmd_size" in extra else None,
        measure=table,
    )
    stats = viewer.run(options)
    if args.benchmark and stats["seconds"] > 0:
        cam = scene.camera
        print(
            f"{args.benchmark} at {cam.width}x{cam.height}: "
            f"{stats['frames'] / stats['seconds']:.1f} fps over "
            f"{stats['frames']} frames ({stats['traces']} traces, {stats['reshades']} re-shades)"
        )
    if args.frames is not None and "readout" in stats:
        print("readout: " + "; ".join(stats["readout_lines"]))
    if args.screenshot is not None:
        print(f"wrote {args.screenshot}")
    return 0
