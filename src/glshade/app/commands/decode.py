"""``glshade decode CAPTURE --out DIR`` (docs/captures.md): a recorded capture (a glshade
``--frames`` folder, or an image stack with ``--coding FILE``) decoded by glshade's own
decoder. Bad input is one line and exit code 2, nothing written; every output is written
atomically."""

from __future__ import annotations

import argparse
import io
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from glshade.app.args import path_arg
from glshade.errors import GlshadeError

#: The PNG maps written beside ``maps.npz``.
PNG_MAPS = ("u", "v", "modulation", "residual")


def add(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "decode",
        help="decode a recorded fringe capture (a --frames folder or an image stack)",
        description="Decode a recorded phase-shifting capture with glshade's decoder: a "
        "glshade --frames folder (manifest.json and its frames), or an image stack (a folder "
        "of 8/16-bit PNG or TIFF frames in name order, or one multi-page TIFF) with --coding "
        "FILE (TOML, docs/captures.md). Writes maps.npz, PNG maps of u, v, modulation and "
        "residual, summary.json and summary.md into --out.",
    )
    p.add_argument("capture", type=path_arg, metavar="CAPTURE", help="a --frames folder or a stack")
    p.add_argument("--coding", type=path_arg, metavar="FILE", help="the stack's coding (TOML)")
    p.add_argument("--out", type=path_arg, metavar="DIR", required=True, help="output directory")
    p.add_argument(
        "--min-modulation-share",
        type=float,
        default=0.1,
        metavar="X",
        help="a pixel is valid where every period's modulation is at least X x amplitude x "
        "the peak response (default 0.1)",
    )


def run(args: argparse.Namespace) -> int:
    from glshade.capture.decode import decode_capture
    from glshade.capture.frames_folder import MANIFEST, read_frames_folder
    from glshade.capture.stack import read_stack
    from glshade.instruments.pmd.files import check_output_dir

    share = args.min_modulation_share
    if not (math.isfinite(share) and share >= 0):
        raise GlshadeError(f"--min-modulation-share: a number of at least 0, got {share}")
    inputs = tuple(p for p in (args.capture, args.coding) if p is not None)
    out = check_output_dir(args.out, "--out", inputs)
    if args.coding is None:
        if not (Path(args.capture) / MANIFEST).is_file():
            raise GlshadeError(
                f"{args.capture}: no {MANIFEST} (a --frames folder); an image stack needs "
                "--coding FILE"
            )
        capture = read_frames_folder(args.capture)
    else:
        capture = read_stack(args.capture, args.coding)
    decoded = decode_capture(capture, share)
    written = write_outputs(out, capture, decoded)
    summary = summary_of(capture, decoded)
    print(f"decoded {capture.source}: valid share {summary['valid_share']:.4f}")
    for path in written:
        print(f"  wrote {path}")
    return 0


def summary_of(capture: Any, decoded: Any) -> dict[str, Any]:
    """The numbers of ``summary.json``."""
    coded = sorted({"u" if d == "u" else "v" for d in capture.coding.directions})
    per_axis: dict[str, Any] = {}
    for name in coded:
        axis = 0 if name == "u" else 1
        valid = decoded.valid
        residual = decoded.residual[axis][valid]
        noise = decoded.noise_mm[axis][valid]
        margin = decoded.margin[axis][valid]
        per_axis[name] = {
            "residual_rms": _median(residual),
            "predicted_noise_mm": _median(noise),
            "least_margin_turns": float(margin.min()) if margin.size else None,
            "finest_modulation": _median(decoded.modulation[axis, 0][valid]),
        }
    return {
        "source": capture.source,
        "frames": int(capture.frames.shape[0]),
        "size": [capture.shape[1], capture.shape[0]],
        "coding": capture.coding.to_dict(),
        "normalised": decoded.normalised,
        "threshold": decoded.threshold,
        "valid_share": decoded.valid_share,
        "axes": per_axis,
        "notes": "medians over the valid pixels; predicted_noise_mm is the decoded "
        "coordinate's noise the N-step fit residual implies (sigma = residual x sqrt(N / "
        "(N - 3)), noise = p_finest / 2 pi x sqrt(2 / N) x sigma / B_finest)",
    }


def _median(values: np.ndarray) -> float | None:
    values = values[np.isfinite(values)]
    return float(np.median(values)) if values.size else None


def write_outputs(out: Path, capture: Any, decoded: Any) -> list[Path]:
    """``maps.npz``, the PNG maps, ``summary.json`` and ``summary.md``, atomically."""
    from glshade.files import atomic_write_bytes, encode_png

    out.mkdir(parents=False, exist_ok=True)
    buf = io.BytesIO()
    np.savez(
        buf,
        uv=decoded.uv,
        fraction=decoded.fraction,
        modulation=decoded.modulation,
        offset=decoded.offset,
        residual=decoded.residual,
        noise_mm=decoded.noise_mm,
        margin=decoded.margin,
        valid=decoded.valid,
    )
    written = [out / "maps.npz"]
    atomic_write_bytes(written[0], buf.getvalue(), "--out", within=out)
    maps = {
        "u": decoded.uv[..., 0],
        "v": decoded.uv[..., 1],
        "modulation": decoded.modulation[:, 0],
        "residual": decoded.residual,
    }
    for name in PNG_MAPS:
        values = np.asarray(maps[name], np.float64)
        if values.ndim == 3:  # per axis: the coded axes side by side
            values = np.concatenate([v for v in values if np.isfinite(v).any()] or [values[0]], 1)
        path = out / f"{name}.png"
        atomic_write_bytes(path, encode_png(_scaled(values), 8), "--out", within=out)
        written.append(path)
    summary = summary_of(capture, decoded)
    path = out / "summary.json"
    atomic_write_bytes(path, (json.dumps(summary, indent=2) + "\n").encode(), "--out", within=out)
    written.append(path)
    path = out / "summary.md"
    atomic_write_bytes(path, summary_markdown(summary).encode(), "--out", within=out)
    written.append(path)
    return written


def _scaled(values: np.ndarray) -> np.ndarray:
    """Values to [0, 1] between their finite extremes (0 where not finite)."""
    finite = values[np.isfinite(values)]
    if not finite.size:
        return np.zeros(values.shape)
    lo, hi = float(finite.min()), float(finite.max())
    span = hi - lo if hi > lo else 1.0
    return np.where(np.isfinite(values), (values - lo) / span, 0.0)


def summary_markdown(summary: dict[str, Any]) -> str:
    """``summary.md``: the summary as a short report."""
    lines = [
        f"# Decoded capture: {summary['source']}",
        "",
        f"- frames: {summary['frames']}, size {summary['size'][0]} x {summary['size'][1]}",
        f"- normalised by white - black: {summary['normalised']}",
        f"- modulation threshold: {summary['threshold']:.6g}",
        f"- valid share: {summary['valid_share']:.4f}",
        "",
        "| axis | finest modulation | residual rms | predicted noise (mm) | least margin (turns) |",
        "|---|---|---|---|---|",
    ]
    for name, values in summary["axes"].items():
        cells = [
            _cell(values[k])
            for k in (
                "finest_modulation",
                "residual_rms",
                "predicted_noise_mm",
                "least_margin_turns",
            )
        ]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n\n" + summary["notes"] + "\n"


def _cell(value: float | None) -> str:
    return "-" if value is None else f"{value:.4g}"
