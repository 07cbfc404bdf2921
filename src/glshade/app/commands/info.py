"""``glshade info``: the GL renderer, its version and fp64 support."""

from __future__ import annotations

import argparse

from glshade import __version__


def add(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("info", help="print the GL renderer, version and fp64 support")
    from glshade.app.args import add_run_flags

    add_run_flags(p, ("device",))


def run(args: argparse.Namespace) -> int:
    from glshade.gpu.context import GLContext

    with GLContext(device_index=args.device) as context:
        info = context.info()
    print(f"glshade {__version__}")
    for line in info.lines():
        print(line)
    return 0
