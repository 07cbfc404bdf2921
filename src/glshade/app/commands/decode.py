"""``glshade decode CAPTURE --out DIR`` (docs/captures.md): a recorded capture (a glshade
``--frames`` folder, an image stack with ``--coding FILE``, or an OpenCSP SOFAST
measurement ``.h5``) decoded by glshade's own decoder. Bad input is one line and exit
code 2, nothing written; every output is written atomically."""

from __future__ import annotations

import argparse
import io
import json
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from glshade.app.args import path_arg
from glshade.errors import GlshadeError

#: The PNG maps written beside ``maps.npz``.
PNG_MAPS = ("u", "v", "modulation", "residual")
H5_SUFFIXES = (".h5", ".hdf5")


def add(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "decode",
        help="decode a recorded fringe capture (a --frames folder, an image stack, a SOFAST .h5)",
        description="Decode a recorded phase-shifting capture with glshade's decoder: a "
        "glshade --frames folder (manifest.json and its frames), an image stack (a folder "
        "of 8/16-bit PNG or TIFF frames in name order, or one multi-page TIFF) with --coding "
        "FILE (TOML, docs/captures.md), or an OpenCSP SOFAST measurement (.h5). Writes "
        "maps.npz, PNG maps, figures, summary.json and summary.md into --out.",
    )
    p.add_argument(
        "capture", type=path_arg, metavar="CAPTURE", help="a --frames folder, a stack or a .h5"
    )
    p.add_argument("--coding", type=path_arg, metavar="FILE", help="the stack's coding (TOML)")
    p.add_argument("--out", type=path_arg, metavar="DIR", required=True, help="output directory")
    p.add_argument(
        "--min-modulation-share",
        type=float,
        default=0.1,
        metavar="X",
        help="a period is sound where its modulation is at least X x amplitude x the peak "
        "response (default 0.1)",
    )
    p.add_argument(
        "--rule",
        choices=("all", "fallback", "periods"),
        default="all",
        help="all: every period sound (the simulator's own rule, default); fallback: decode "
        "from the finest period from which on every one is sound; periods: from the finest "
        "period whose coarser periods are sound and unwrap it unambiguously (its own "
        "modulation at least half the threshold, every margin at least 0.25 turn)",
    )
    p.add_argument(
        "--response",
        metavar="SPEC",
        help="the display response: gamma:G, a curve (.csv or .toml: recorded, commanded), "
        "or an OpenCSP image_calibration.h5",
    )
    p.add_argument(
        "--mask",
        choices=("region", "lit", "all"),
        default="region",
        help="with black and white references: the lit pixels' largest region (default), "
        "every lit pixel, or all pixels (no mask)",
    )
    p.add_argument(
        "--noise",
        metavar="SPEC",
        help="the camera's noise, read=R,gain=G[,q=Q] in recorded units (G per electron), "
        "for the predicted noise (default: a glshade capture's sensor)",
    )
    p.add_argument(
        "--display",
        type=path_arg,
        metavar="FILE",
        help="a SOFAST capture's screen shape (OpenCSP display_distorted_2d.h5): screen "
        "points on the calibrated screen, and its size for the mm maps",
    )


def run(args: argparse.Namespace) -> int:
    from glshade.capture.decode import decode_capture

    share = args.min_modulation_share
    if not (math.isfinite(share) and share >= 0):
        raise GlshadeError(f"--min-modulation-share: a number of at least 0, got {share}")
    settings = _settings(args)
    capture, display = _read(args)
    inputs = tuple(Path(p) for p in (args.capture, args.coding, args.display) if p is not None)
    if settings.response is not None and settings.response.file is not None:
        inputs += (settings.response.file,)
    from glshade.instruments.pmd.files import check_output_dir

    out = check_output_dir(args.out, "--out", inputs)
    decoded = decode_capture(capture, settings=settings)
    linear = None
    if settings.response is not None:
        bare = replace(settings, response=None)
        linear = decode_capture(replace(capture, response=None), settings=bare)
    screen = _screen_points(display, decoded) if display is not None else None
    written = write_outputs(out, capture, decoded, linear, screen)
    summary = summary_of(capture, decoded, linear)
    print(f"decoded {capture.source}: valid share {summary['valid_share']:.4f}")
    print(
        f"  status: {summary['status']}"
        + (f" ({summary['status_reason']})" if summary["status_reason"] else "")
    )
    if summary.get("response_check"):
        print(f"  {summary['response_check']['verdict']}")
    for path in written:
        print(f"  wrote {path}")
    return 0


def _settings(args: argparse.Namespace) -> Any:
    from glshade.capture.decode import DecodeSettings
    from glshade.capture.noise import parse_noise
    from glshade.capture.response_files import parse_response

    response = None if args.response is None else parse_response(args.response)
    noise = None if args.noise is None else parse_noise(args.noise)
    return DecodeSettings(args.min_modulation_share, args.rule, response, noise, args.mask)


def _read(args: argparse.Namespace) -> tuple[Any, Any]:
    """The capture, and a SOFAST capture's display shape (or None)."""
    from glshade.capture.frames_folder import MANIFEST, read_frames_folder
    from glshade.capture.stack import read_stack

    path = Path(args.capture)
    if path.suffix.lower() in H5_SUFFIXES:
        from glshade.capture.sofast import EXTENT_MM, read_sofast_capture
        from glshade.capture.sofast_station import read_sofast_display

        if not path.is_file():
            raise GlshadeError(f"{path}: no such file (a SOFAST measurement .h5)")
        display = None if args.display is None else read_sofast_display(args.display)
        size = (EXTENT_MM, EXTENT_MM)
        if display is not None:
            matrix = display.affine()[0]
            size = (float(abs(matrix[0, 0])), float(abs(matrix[1, 1])))
        return read_sofast_capture(path, screen_size_mm=size), display
    if args.display is not None:
        raise GlshadeError(f"--display {args.display}: for a SOFAST capture (.h5) only")
    if args.coding is None:
        if not (path / MANIFEST).is_file():
            raise GlshadeError(
                f"{args.capture}: no {MANIFEST} (a --frames folder); an image stack needs "
                "--coding FILE; a SOFAST measurement ends in .h5"
            )
        return read_frames_folder(path), None
    return read_stack(path, args.coding), None


def _screen_points(display: Any, decoded: Any) -> np.ndarray:
    """(H, W, 3) the decoded fractions on the calibrated screen (mm, screen coordinates;
    SOFAST's fractions: x as decoded, y as decoded, both from the screen's low edge of its
    own coordinates)."""
    points = np.full((*decoded.valid.shape, 3), np.nan)
    ok = decoded.valid & np.isfinite(decoded.fraction).all(axis=-1)
    points[ok] = display.screen_mm(decoded.fraction[ok][:, 0], decoded.fraction[ok][:, 1])
    return points


# --------------------------------------------------------------------------- summary
def summary_of(capture: Any, decoded: Any, linear: Any = None) -> dict[str, Any]:
    """The numbers of ``summary.json``."""
    coded = sorted({"u" if d == "u" else "v" for d in capture.coding.directions})
    per_axis = {name: _axis_numbers(decoded, 0 if name == "u" else 1) for name in coded}
    summary: dict[str, Any] = {
        "source": capture.source,
        "frames": int(capture.frames.shape[0]),
        "size": [capture.shape[1], capture.shape[0]],
        "coding": capture.coding.to_dict(),
        "response": decoded.response,
        "normalised": decoded.normalised,
        "threshold": decoded.threshold,
        "peak": decoded.peak,
        "lit_threshold": decoded.lit_threshold,
        "valid_share": decoded.valid_share,
        "valid_pixels": int(decoded.valid.sum()),
        "lit_pixels": None if decoded.lit is None else int(decoded.lit.sum()),
        "region_pixels": None if decoded.region is None else int(decoded.region.sum()),
        "axes": per_axis,
        "notes": "medians over the valid pixels unless named rms; noise_from_residual_mm is "
        "the decoded coordinate's noise the N-step fit residual implies (sigma = residual x "
        "sqrt(N / (N - 3)), noise = p / 2 pi x sqrt(2 / N) x sigma / B for the finest period "
        "used); predicted_noise_mm the camera's noise model's (read, shot, quantisation: "
        "--noise, or a glshade capture's sensor; none without one)",
    }
    if linear is not None:
        summary["response_check"] = response_check(decoded, linear, coded)
    summary["status"], summary["status_reason"] = decode_status(per_axis)
    return summary


#: The least unwrapping margin (turns) below which a decoded map is at risk of a pixel on
#: the wrong fringe.
RISKY_MARGIN_TURNS = 0.1


def decode_status(per_axis: dict[str, Any]) -> tuple[str, str]:
    """``(status, reason)``: "no valid pixel" where an axis has none, "unwrapping at risk"
    where its least margin is below :data:`RISKY_MARGIN_TURNS`, else "ok"."""
    empty = [name for name, values in per_axis.items() if values["least_margin_turns"] is None]
    if empty:
        return "no valid pixel", f"no pixel decodes along {', '.join(empty)}"
    risky = {
        name: values["least_margin_turns"]
        for name, values in per_axis.items()
        if values["least_margin_turns"] < RISKY_MARGIN_TURNS
    }
    if risky:
        worst = ", ".join(f"{name} {margin:.3f}" for name, margin in risky.items())
        return (
            "unwrapping at risk",
            f"least unwrapping margin {worst} turn (< {RISKY_MARGIN_TURNS})",
        )
    return "ok", ""


def _axis_numbers(decoded: Any, axis: int) -> dict[str, Any]:
    valid = decoded.valid
    used = decoded.finest_used[axis]
    predicted = decoded.predicted_noise_mm
    return {
        "residual": _median(decoded.residual[axis][valid]),
        "period_residual": [_median(r[valid]) for r in decoded.period_residual[axis]],
        "modulation": [_median(m[valid]) for m in decoded.modulation[axis]],
        "period_valid_share": [float(v.mean()) for v in decoded.period_valid[axis]],
        "pixels_by_finest_period_used": [
            int((valid & (used == k)).sum()) for k in range(decoded.modulation.shape[1])
        ],
        "noise_from_residual_mm": _median(decoded.noise_mm[axis][valid]),
        "noise_from_residual_rms_mm": _rms(decoded.noise_mm[axis][valid]),
        "predicted_noise_rms_mm": None if predicted is None else _rms(predicted[axis][valid]),
        "least_margin_turns": _least(decoded.margin[axis][valid]),
    }


def response_check(decoded: Any, linear: Any, coded: list[str]) -> dict[str, Any]:
    """Per coded axis, the median over the pixels valid in both of the N-step fit's
    residual (as a share of white - black: over each decoding's peak) and of the
    residual over the coarsest period's modulation, with the response and without. A
    response that describes the capture leaves a purer sinusoid; the residual alone
    is no fair judge (the response stretches the values it is measured in), the ratio
    to the modulation in the same values is: the smaller says which the data support."""
    both = decoded.valid & linear.valid
    axes = [(n, 0 if n == "u" else 1) for n in coded]
    residual, ratios = {}, {}
    for label, result in (("with", decoded), ("without", linear)):
        residual[label] = {n: _median(result.residual[a][both] / result.peak) for n, a in axes}
        ratios[label] = {
            n: _median(result.residual[a][both] / result.modulation[a, -1][both]) for n, a in axes
        }
    with_total = float(np.nanmean([v for v in ratios["with"].values() if v is not None]))
    without_total = float(np.nanmean([v for v in ratios["without"].values() if v is not None]))
    supported = "with" if with_total < without_total else "without"
    verdict = (
        f"the data support decoding {supported} the response ({decoded.response}): the fit "
        f"residual is {min(with_total, without_total):.4g} of the modulation {supported} it, "
        f"{max(with_total, without_total):.4g} {'without' if supported == 'with' else 'with'} it"
    )
    return {
        "pixels": int(both.sum()),
        "residual_share": residual,
        "residual_over_modulation": ratios,
        "supported": supported,
        "verdict": verdict,
    }


def _median(values: np.ndarray) -> float | None:
    values = values[np.isfinite(values)]
    return float(np.median(values)) if values.size else None


def _rms(values: np.ndarray) -> float | None:
    values = values[np.isfinite(values)]
    return float(np.sqrt(np.mean(values**2))) if values.size else None


def _least(values: np.ndarray) -> float | None:
    values = values[np.isfinite(values)]
    return float(values.min()) if values.size else None


# --------------------------------------------------------------------------- outputs
def write_outputs(
    out: Path, capture: Any, decoded: Any, linear: Any = None, screen: np.ndarray | None = None
) -> list[Path]:
    """``maps.npz``, the PNG maps, the figures, ``summary.json`` and ``summary.md``,
    atomically."""
    from glshade.files import atomic_write_bytes, encode_png

    out.mkdir(parents=False, exist_ok=True)
    arrays = {
        name: getattr(decoded, name)
        for name in (
            "uv",
            "fraction",
            "modulation",
            "offset",
            "period_valid",
            "finest_used",
            "residual",
            "period_residual",
            "noise_mm",
            "margin",
            "valid",
        )
    }
    for name in ("predicted_noise_mm", "lit", "region"):
        if getattr(decoded, name) is not None:
            arrays[name] = getattr(decoded, name)
    if screen is not None:
        arrays["screen_mm"] = screen
        arrays["screen_m"] = screen / 1000.0
    buf = io.BytesIO()
    np.savez(buf, **arrays)
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
    written += write_figures(out, capture, decoded)
    summary = summary_of(capture, decoded, linear)
    for name, text in (
        ("summary.json", json.dumps(summary, indent=2) + "\n"),
        ("summary.md", summary_markdown(summary)),
    ):
        atomic_write_bytes(out / name, text.encode(), "--out", within=out)
        written.append(out / name)
    return written


def write_figures(out: Path, capture: Any, decoded: Any) -> list[Path]:
    """``periods.png`` (modulation and residual per axis and period) and ``masks.png``
    (lit, region, valid, the finest period used)."""
    from matplotlib.figure import Figure

    from glshade.instruments.figures import save_figure

    axes = [a for a in (0, 1) if np.isfinite(decoded.modulation[a]).any()]
    count = decoded.modulation.shape[1]
    fig = Figure(figsize=(2.6 * count, 2.3 * 2 * len(axes)))
    rows = [
        (a, name, values)
        for a in axes
        for name, values in (
            ("modulation", decoded.modulation[a]),
            ("residual", decoded.period_residual[a]),
        )
    ]
    for row, (a, name, values) in enumerate(rows):
        for k in range(count):
            ax = fig.add_subplot(2 * len(axes), count, row * count + k + 1)
            image = ax.imshow(np.where(decoded.valid, values[k], np.nan), cmap="viridis")
            fig.colorbar(image, ax=ax, shrink=0.75)
            ax.set_title(f"{'uv'[a]} {name}, period {k + 1} (finest 1)", fontsize=7)
            ax.set_axis_off()
    save_figure(fig, out / "periods.png", within=out)
    panels = [("valid", decoded.valid)]
    panels += [
        (f"{'uv'[a]}: finest period used", decoded.finest_used[a].astype(float)) for a in axes
    ]
    panels += [
        (name, getattr(decoded, name))
        for name in ("lit", "region")
        if getattr(decoded, name) is not None
    ]
    fig = Figure(figsize=(2.8 * len(panels), 2.6))
    for i, (title, values) in enumerate(panels):
        ax = fig.add_subplot(1, len(panels), i + 1)
        ax.imshow(np.asarray(values, float), cmap="magma")
        ax.set_title(title, fontsize=8)
        ax.set_axis_off()
    save_figure(fig, out / "masks.png", within=out)
    return [out / "periods.png", out / "masks.png"]


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
        f"Status: **{summary['status']}**"
        + (f": {summary['status_reason']}" if summary["status_reason"] else ""),
        "",
        f"- frames: {summary['frames']}, size {summary['size'][0]} x {summary['size'][1]}",
        f"- response: {summary['response']}; normalised by white - black: {summary['normalised']}",
        f"- modulation threshold: {summary['threshold']:.6g}",
        f"- valid: {summary['valid_pixels']} pixels, share {summary['valid_share']:.4f}"
        + (
            f" (lit {summary['lit_pixels']}, region {summary['region_pixels']})"
            if summary["lit_pixels"] is not None
            else ""
        ),
        "",
        "| axis | residual | noise from residual (rms, mm) | predicted noise (rms, mm) "
        "| least margin (turns) | pixels by finest period used |",
        "|---|---|---|---|---|---|",
    ]
    for name, values in summary["axes"].items():
        cells = [
            _cell(values[k])
            for k in (
                "residual",
                "noise_from_residual_rms_mm",
                "predicted_noise_rms_mm",
                "least_margin_turns",
            )
        ]
        used = ", ".join(str(n) for n in values["pixels_by_finest_period_used"])
        lines.append(f"| {name} | " + " | ".join(cells) + f" | {used} |")
    check = summary.get("response_check")
    if check:
        lines += ["", f"Response: {check['verdict']}.", ""]
        lines += _check_table(check)
    return "\n".join(lines) + "\n\n" + summary["notes"] + "\n"


def _check_table(check: dict[str, Any]) -> list[str]:
    """The response check's medians (over the pixels valid both ways), per axis."""
    lines = [
        "| axis | residual / (white - black), with | without | residual / modulation, with "
        "| without |",
        "|---|---|---|---|---|",
    ]
    for name in check["residual_share"]["with"]:
        cells = [
            _cell(check[key][label][name])
            for key in ("residual_share", "residual_over_modulation")
            for label in ("with", "without")
        ]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    return lines


def _cell(value: float | None) -> str:
    return "-" if value is None else f"{value:.4g}"
