"""``glshade accuracy``: every knob's error against its run time, and the stability matrix."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from glshade.app.args import path_arg
from glshade.errors import GlshadeError
from glshade.scene import Camera


def add(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "accuracy",
        help="measure error against run time for every knob, and the stability matrix",
        description="Write OUT/accuracy.md and OUT/figures/accuracy_*.png: each knob's error "
        "against a "
        "converged reference (uv, image, visibility) and its run time, the Pareto fronts, the "
        "shipped "
        "defaults, and the stability table of the extreme cases. 'glshade accuracy --out docs' "
        "regenerates the repository's report (a few minutes).",
    )
    p.add_argument(
        "--out",
        type=path_arg,
        default=Path("accuracy"),
        metavar="DIR",
        help="output directory (default %(default)s)",
    )
    p.add_argument(
        "--repeats",
        type=int,
        default=5,
        metavar="K",
        help="timed repeats per setting (default %(default)s)",
    )
    p.add_argument(
        "--size",
        type=int,
        default=256,
        metavar="N",
        help="pixels across for the per-frame knobs (default %(default)s)",
    )
    p.add_argument(
        "--scenes",
        default="flat,cylinder,sphere",
        metavar="LIST",
        help="surface kinds of the knobs' paper scenes (default %(default)s)",
    )


def run(args: argparse.Namespace) -> int:
    from glshade.validation import accuracy

    if args.repeats < 1:
        raise GlshadeError(f"--repeats: must be an integer >= 1, got {args.repeats}")
    if args.out.exists() and not args.out.is_dir():
        raise GlshadeError(f"--out {args.out}: is not a directory")
    Camera().resampled(args.size)
    surfaces = tuple(part.strip() for part in args.scenes.split(",") if part.strip())
    path = accuracy.run(
        args.out,
        repeats=args.repeats,
        size=args.size,
        surfaces=surfaces,
        log=lambda m: print(m, file=sys.stderr),
    )
    print(f"wrote {path}")
    return 0
