"""``glshade measure``: how visible a scene's defect is, by any registered instrument
(``--method``; default: the one the scene's emitter is measured by). The instrument's
settings flags, the files it writes, its checks, its numbers and how it prints them all
come from the instrument (:class:`glshade.instruments.base.Instrument`)."""

from __future__ import annotations

import argparse
import json
import time
from typing import Any

from glshade.app.args import (
    add_scene_flags,
    add_settings_flags,
    check_outputs,
    instrument_settings,
    path_arg,
    run_inputs,
    save_scene,
    scene_from_args,
    scene_measure_table,
    warn,
)
from glshade.errors import GlshadeError
from glshade.instruments.registry import instrument, instruments
from glshade.measure.single import method_for, methods
from glshade.oracle.advice import scene_warnings
from glshade.process import reuse_freed_memory


def add(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "measure",
        help="how visible is a scene's defect (the three numbers of docs/study.md)",
        description="Render a scene with and without its defect and measure the defect's "
        "visibility with an instrument: by default the paper's metric (visibility_px), its "
        "continuous limit (visibility_continuous_px), how far the rays move (deflection_px), "
        "whether the stripe map folds, its islands and the best phase, beside the closed "
        "forms (docs/physics.md); --method pmd: what a phase-measuring station measures. "
        "Scene and flags as for render.",
    )
    add_scene_flags(p)
    p.add_argument("--json", action="store_true", help="print one JSON object instead of a table")
    add_instrument_flags(p)


def add_instrument_flags(p: argparse.ArgumentParser) -> None:
    """``--method``, and every registered instrument's file options and settings flags."""
    p.add_argument(
        "--method",
        choices=methods(),
        help="the instrument: "
        + "; ".join(f"{name} ({item.title})" for name, item in instruments().by_name.items())
        + ". Default: the one the scene's emitter is measured by (pmd where it shows fringes, "
        "else paper); pmd on a scene of stripes shows the fringes on the same screen",
    )
    for item in instruments().by_name.values():
        for option in item.file_options:
            if option.kind == "choice":
                p.add_argument(option.flag, dest=option.dest, choices=option.choices,
                               default=option.default, help=option.help)  # fmt: skip
            else:
                p.add_argument(option.flag, dest=option.dest, type=path_arg,
                               metavar=option.metavar, help=option.help)  # fmt: skip
    add_settings_flags(p)


def files_given(args: argparse.Namespace, chosen: Any) -> dict[str, Any]:
    """The chosen instrument's file options from the command line (flag -> value); a file
    option of another instrument is one line."""
    for item in instruments().by_name.values():
        for option in item.file_options:
            given = getattr(args, option.dest, None)
            if item is not chosen and option.kind != "choice" and given is not None:
                raise GlshadeError(
                    f"{option.flag}: belongs to {item.title} (--method {item.name}), not to "
                    f"--method {chosen.name}"
                )
    return {option.flag: getattr(args, option.dest, None) for option in chosen.file_options}


def run(args: argparse.Namespace) -> int:
    from glshade.gpu.context import GLContext
    from glshade.gpu.renderer import Renderer

    scene = scene_from_args(args)
    table = scene_measure_table(args, scene)
    named = table.method if table.named else None
    chosen = instrument(method_for(scene, args.method or named))
    scene = chosen.prepared(scene)
    settings = instrument_settings(args, chosen.name, table=table)
    files = files_given(args, chosen)
    chosen.check_case(scene, settings)
    outputs = [
        (option.flag, files[option.flag], option.suffixes)
        for option in chosen.file_options
        if option.kind == "file" and files[option.flag] is not None
    ]
    check_outputs(args, scene, outputs)
    chosen.check_files(files, scene, run_inputs(args, scene))
    warn(scene_warnings(scene))
    reuse_freed_memory()  # the phases' temporaries: about 40 ms of page faults otherwise
    start = time.perf_counter()
    with (
        GLContext(device_index=args.device) as context,
        Renderer(context, progress=True) as renderer,
    ):
        result = chosen.measure_files(renderer, scene, settings, files)
    seconds = time.perf_counter() - start
    record = chosen.record(scene, result)
    written = chosen.write_files(files, scene, result)
    save_scene(args, scene)
    warn(chosen.warnings(scene, result))
    if args.json:
        size = [scene.camera.width, scene.camera.height]
        out = {**record.outputs(), "scene": scene.title(), "size": size}
        print(json.dumps({**out, "seconds": round(seconds, 3)}))
        return 0
    print("\n".join(chosen.summary_lines(scene, record)))
    for line in written:
        print(f"  wrote {line}")
    return 0
