"""``glshade finding3``: the paper's finding 3 under realistic optics."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from glshade.app.args import path_arg
from glshade.errors import GlshadeError
from glshade.scene import Camera


def add(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "finding3",
        help="the paper's finding 3 under realistic optics (eq. (1) roughness, lens, Fresnel, "
        "sensor)",
        description="Measure visibility against theta for the paper's gentle and steep 5 um dents "
        "on the flat "
        "plate with the ideal mirror and with each realistic effect alone and combined; write "
        "OUT/finding3.csv, finding3.png and finding3.md ('glshade paper --out OUT' then quotes "
        "the verdicts). "
        "About 14 minutes at the default size on 2 CPU cores.",
    )
    p.add_argument(
        "--out",
        type=path_arg,
        default=Path("paper_study"),
        metavar="DIR",
        help="output directory (default %(default)s)",
    )
    p.add_argument(
        "--size", type=int, default=512, metavar="N", help="pixels across (default %(default)s)"
    )


def run(args: argparse.Namespace) -> int:
    from glshade.study import finding3

    if args.out.exists() and not args.out.is_dir():
        raise GlshadeError(f"--out {args.out}: is not a directory")
    Camera().resampled(args.size)
    if args.size < 256:
        raise GlshadeError(
            f"--size: must be at least 256 (the stripes need 4 pixels a period), got {args.size}"
        )
    path = finding3.run(
        args.out,
        size=args.size,
        progress=lambda row: print(
            f"{row['variant']:>13} theta {row['theta_deg']:>4g} sigma2 {row['sigma2_mm2']:>3g}: "
            f"{row['visibility_px']:g} px ({row['seconds']:.1f} s)"
            + ("" if row["status"] == "ok" else f" [{row['status']}: not measurable]"),
            file=sys.stderr,
        ),
    )
    print(f"wrote {path}")
    return 0
