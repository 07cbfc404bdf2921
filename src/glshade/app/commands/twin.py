"""``glshade twin MEASUREMENT --out DIR`` (docs/twin.md): a real SOFAST single-facet
measurement reconstructed by glshade (its decoder, the facet's pose, SOFAST's slope
solver), the station's digital twin rendered, and the two compared. Bad input is one
line and exit code 2, nothing written; every output is written atomically."""

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

SURFACES = ("nominal", "fitted")


def add(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "twin",
        help="a real SOFAST facet measurement: its slopes, and the station's digital twin",
        description="Reconstruct a real SOFAST (OpenCSP) single-facet measurement with "
        "glshade (decode, the facet's pose from its corners, SOFAST's slope solver), render "
        "the station's twin (camera, screen, the nominal or fitted facet) and compare them. "
        "The station's files are read from --station DIR under OpenCSP's names "
        "(camera_sofast_downsampled.h5, display_distorted_2d.h5, spatial_orientation.h5, "
        "Facet_NSTTF.json, and image_calibration.h5 when present). Writes twin.npz, "
        "twin_x.toml and twin_y.toml (the twin's scenes), slopes.png, deviation.png, "
        "frames.png, summary.json and summary.md into --out.",
    )
    p.add_argument("measurement", type=path_arg, metavar="MEASUREMENT", help="measurement .h5")
    p.add_argument(
        "--station",
        type=path_arg,
        metavar="DIR",
        help="the station's files (default: beside MEASUREMENT)",
    )
    p.add_argument("--out", type=path_arg, metavar="DIR", required=True, help="output directory")
    p.add_argument(
        "--surface", choices=SURFACES, default="nominal", help="the twin's facet (default nominal)"
    )
    p.add_argument(
        "--focal",
        type=float,
        nargs=2,
        default=(100.0, 100.0),
        metavar=("FX_M", "FY_M"),
        help="the design focal lengths along x and y, metres (default 100 100)",
    )
    p.add_argument(
        "--supersample",
        type=int,
        default=4,
        metavar="N",
        help="the twin's rays per pixel side: N x N rays integrate each pixel (default 4)",
    )
    p.add_argument("--raw", action="store_true", help="ignore the display-response calibration")
    p.add_argument("--no-render", action="store_true", help="reconstruct only; no twin frames")


def _inputs(args: argparse.Namespace) -> dict[str, Path]:
    from glshade.capture.sofast_station import station_paths

    folder = Path(args.station) if args.station is not None else Path(args.measurement).parent
    paths = station_paths(folder)
    for key, path in paths.items():
        if key != "calibration" and not path.is_file():
            raise GlshadeError(f"--station {folder}: no {path.name} (the station's {key} file)")
    if not Path(args.measurement).is_file():
        raise GlshadeError(f"{args.measurement}: no such measurement file")
    return paths


def run(args: argparse.Namespace) -> int:
    from glshade.capture.sofast import read_sofast_calibration, read_sofast_measurement
    from glshade.capture.sofast_station import read_sofast_station
    from glshade.instruments.pmd.files import check_output_dir

    focal = tuple(float(v) for v in args.focal)
    if not all(math.isfinite(v) and v > 0 for v in focal):
        raise GlshadeError(f"--focal {args.focal[0]} {args.focal[1]}: two lengths above 0 (metres)")
    from glshade.components.render.sampling.table import MAX_SUPERSAMPLE

    if not 1 <= args.supersample <= MAX_SUPERSAMPLE:
        raise GlshadeError(f"--supersample {args.supersample}: an integer 1 to {MAX_SUPERSAMPLE}")
    paths = _inputs(args)
    out = check_output_dir(args.out, "--out", (Path(args.measurement), *paths.values()))
    station = read_sofast_station(
        paths["camera"], paths["display"], paths["orientation"], paths["facet"]
    )
    measurement = read_sofast_measurement(args.measurement)
    calibration = None
    if not args.raw and paths["calibration"].is_file():
        calibration = read_sofast_calibration(paths["calibration"])
    design = (1000 * focal[0], 1000 * focal[1])
    result = _run(station, measurement, calibration, args, design)
    result.summary["calibration"] = str(paths["calibration"]) if calibration is not None else None
    for path in write_outputs(out, result):
        print(f"  wrote {path}")
    fx, fy = result.summary["focal_lengths_m"]
    status = result.summary["status"]
    reason = result.summary["status_reason"]
    print(f"facet: {result.summary['pixels']} pixels, focal lengths {fx:.2f} m, {fy:.2f} m")
    print(f"status: {status}" + (f" ({reason})" if reason else ""))
    return 0


def _run(
    station: Any, measurement: Any, calibration: Any, args: argparse.Namespace, design: Any
) -> Any:
    from glshade.twin.run import run_twin

    if args.no_render:
        return run_twin(station, measurement, calibration, None, args.surface, design)
    from glshade.gpu.context import GLContext
    from glshade.gpu.renderer import Renderer

    ss = args.supersample
    with GLContext() as context, Renderer(context) as renderer:
        return run_twin(station, measurement, calibration, renderer, args.surface, design, ss)


def write_outputs(out: Path, result: Any) -> list[Path]:
    """The maps, the twin's scenes, the figures and the summary, atomically."""
    from glshade.files import atomic_write_bytes

    out.mkdir(parents=False, exist_ok=True)
    m = result.measured
    maps = {
        "mask": m.mask,
        "slopes": m.slopes,
        "screen_mm": m.screen_mm,
        "fraction": m.fraction,
        "deviation_from_design": result.deviation.from_design,
        "deviation_from_fit": result.deviation.from_fit,
        "deviation_from_twin": result.deviation.from_twin,
        "screen_deviation_mm": result.deviation.screen_mm,
    }
    if result.twin_screen_mm is not None:
        maps["twin_screen_mm"] = result.twin_screen_mm
    buffer = io.BytesIO()
    np.savez_compressed(buffer, **maps)
    written = [out / "twin.npz"]
    atomic_write_bytes(written[0], buffer.getvalue(), "--out", within=out)
    for direction, scene in result.scenes.items():
        path = out / f"twin_{direction}.toml"
        scene.save(path)
        written.append(path)
    written += write_figures(out, result)
    summary = result.summary
    for name, text in (
        ("summary.json", json.dumps(summary, indent=2) + "\n"),
        ("summary.md", summary_markdown(summary)),
    ):
        atomic_write_bytes(out / name, text.encode(), "--out", within=out)
        written.append(out / name)
    return written


def write_figures(out: Path, result: Any) -> list[Path]:
    """slopes.png, deviation.png and (when rendered) frames.png."""
    from matplotlib.figure import Figure

    from glshade.instruments.figures import save_figure

    written = []
    panels = {
        "slopes.png": [
            ("slope x (mrad)", result.measured.slopes[0]),
            ("slope y (mrad)", result.measured.slopes[1]),
        ],
        "deviation.png": [
            (
                "x slope - twin (mrad)",
                _or(result.deviation.from_twin[0], result.deviation.from_design[0]),
            ),
            (
                "y slope - twin (mrad)",
                _or(result.deviation.from_twin[1], result.deviation.from_design[1]),
            ),
            ("x slope - fit (mrad)", result.deviation.from_fit[0]),
            ("y slope - fit (mrad)", result.deviation.from_fit[1]),
        ],
    }
    for name, items in panels.items():
        fig = Figure(figsize=(4.2 * len(items), 3.4))
        for i, (title, values) in enumerate(items):
            ax = fig.add_subplot(1, len(items), i + 1)
            limit = float(np.nanpercentile(np.abs(values), 99)) * 1e3 or 1.0
            image = ax.imshow(values * 1e3, cmap="coolwarm", vmin=-limit, vmax=limit)
            fig.colorbar(image, ax=ax, shrink=0.8)
            ax.set_title(title, fontsize=9)
            ax.set_axis_off()
        save_figure(fig, out / name, within=out)
        written.append(out / name)
    if result.twin_radiance:
        written.append(_frames_figure(out, result))
    return written


def _or(values: np.ndarray, otherwise: np.ndarray) -> np.ndarray:
    """``values`` where any is finite (the twin was rendered), else ``otherwise``."""
    return values if np.isfinite(values).any() else otherwise


def _frames_figure(out: Path, result: Any) -> Path:
    """Each period's first frame along x and y: the real one above, the twin's below."""
    from matplotlib.figure import Figure

    from glshade.instruments.figures import save_figure
    from glshade.twin.geometry import polygon_mask

    facet = polygon_mask(result.measured.pose.corners_px, result.measured.mask.shape)
    columns = [(d, k) for d in ("x", "y") for k in range(result.twin_radiance[d].shape[0])]
    fig = Figure(figsize=(1.9 * len(columns), 3.4))
    for col, (direction, k) in enumerate(columns):
        for row, (name, frames) in enumerate(
            (("real", result.real_frames), ("twin", result.twin_radiance))
        ):
            ax = fig.add_subplot(2, len(columns), row * len(columns) + col + 1)
            shown = frames[direction][k, 0] * (facet if name == "twin" else 1.0)
            ax.imshow(shown, cmap="gray")
            ax.set_title(f"{name} {direction}{k + 1}", fontsize=7)
            ax.set_axis_off()
    path = out / "frames.png"
    save_figure(fig, path, within=out)
    return path


def summary_markdown(summary: dict[str, Any]) -> str:
    """summary.md: the facet, the pose, the deviation, the frames beside."""
    fx, fy = summary["focal_lengths_m"]
    lines = [
        "# A real facet and its twin",
        "",
        f"Status: **{summary['status']}**"
        + (f": {summary['status_reason']}" if summary["status_reason"] else ""),
        "",
        f"- pixels reconstructed: {summary['pixels']} (lit: {summary['lit_pixels']})",
        f"- focal lengths: {fx:.3f} m (x), {fy:.3f} m (y); design "
        f"{summary['design_focal_lengths_m'][0]:g} m, {summary['design_focal_lengths_m'][1]:g} m",
        f"- corners' reprojection: {summary['reprojection_px']:.3f} px rms; the alignment "
        f"turned the data by {summary['alignment_turn_mrad']:.2f} mrad",
        "- slope deviation from the design parabola (rms, x, y): "
        + ", ".join(f"{v:.4f} mrad" for v in summary["slope_rms_from_design_mrad"]),
        "- slope deviation from the fitted parabola (rms, x, y): "
        + ", ".join(f"{v:.4f} mrad" for v in summary["slope_rms_from_fit_mrad"]),
        "- the calibrated screen departs from a flat rectangle by "
        f"{summary['screen_shape_rms_mm']:.2f} mm rms",
    ]
    if summary["screen_deviation_rms_mm"] is not None:
        rx, ry = summary["screen_deviation_rms_mm"]
        lines.append(
            f"- measured screen points less the {summary['twin_surface']} twin's: "
            f"{rx:.2f} mm (x), {ry:.2f} mm (y) rms"
        )
    loop = summary.get("twin_reconstructed")
    if loop is not None:
        lx, ly = loop["focal_lengths_m"]
        lines += [
            "- the twin's frames decoded and solved alike: focal lengths "
            f"{lx:.3f} m, {ly:.3f} m; slopes within "
            + ", ".join(f"{v:.4f}" for v in loop["slope_error_rms_mrad"])
            + " mrad rms of the twin's facet",
            "- measured slopes less the twin's (rms, x, y): "
            + ", ".join(f"{v:.4f} mrad" for v in summary["slope_rms_from_twin_mrad"]),
        ]
    if summary["frames"]:
        lines += [
            "",
            "| direction | periods per screen | real modulation | twin modulation | real / twin "
            "| real offset |",
            "|---|---|---|---|---|---|",
        ]
        for direction, block in summary["frames"].items():
            for row in block["periods"]:
                lines.append(
                    f"| {direction} | {row['periods_per_screen']:g} | "
                    f"{row['real_modulation_share']:.3f} | "
                    f"{row['twin_modulation_share']:.3f} | {row['real_to_twin']:.3f} | "
                    f"{row['real_offset_share']:.3f} |"
                )
        lines.append("")
        for direction, block in summary["frames"].items():
            lines.append(
                f"- {direction}: median fit residual {block['residual_counts_median']:.3g} "
                "counts (raw frames; "
                f"{block['residual_share_median']:.4f} of white - black)"
            )
    return "\n".join(lines) + "\n"
