"""``glshade bench``: the shaders (fp32, fp64) timed against the NumPy reference."""

from __future__ import annotations

import argparse

from glshade.app.args import add_run_flags
from glshade.errors import GlshadeError
from glshade.scene import Camera


def add(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "bench",
        help="time the shaders (fp32, fp64) against the NumPy reference",
        description="Render the paper's flat scene (theta 45) and report the median time per frame "
        "and megapixels per second for the fp32 and fp64 shaders and the NumPy fp64 reference.",
    )
    p.add_argument(
        "--size", type=int, default=1024, metavar="N", help="pixels across (default %(default)s)"
    )
    p.add_argument("--theta", type=float, default=45.0, metavar="DEG")
    p.add_argument(
        "--repeats",
        type=int,
        default=9,
        metavar="K",
        help="frames timed per shader (default %(default)s)",
    )
    p.add_argument(
        "--reference-rows", type=int, metavar="R", help="trace only R rows with NumPy and scale"
    )
    add_run_flags(p, ("device",))


def run(args: argparse.Namespace) -> int:
    from glshade.validation import bench

    if args.repeats < 1:
        raise GlshadeError(f"--repeats: must be an integer >= 1, got {args.repeats}")
    if args.reference_rows is not None and args.reference_rows < 1:
        raise GlshadeError(f"--reference-rows: must be an integer >= 1, got {args.reference_rows}")
    Camera().resampled(args.size)  # validates --size
    timings, gl_renderer = bench.run(
        args.size, args.theta, args.repeats, args.reference_rows, args.device
    )
    print(bench.report(timings, gl_renderer, args.size, args.theta, args.repeats))
    return 0
