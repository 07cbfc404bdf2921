"""``glshade station``: a picture of the station (camera, screen, part, the dent and a
bundle of reflected rays, in the world frame) and its numbers (:mod:`glshade.scene.
station_report`): working distance, incidence at the dent, where the reflected chief ray
lands on the screen, how much of the screen the camera sees and how finely."""

from __future__ import annotations

import argparse
import io
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from glshade.app.args import (
    add_scene_flags,
    check_outputs,
    path_arg,
    save_scene,
    scene_from_args,
)

if TYPE_CHECKING:
    from mpl_toolkits.mplot3d import Axes3D

    from glshade.oracle.station_report import StationReport
    from glshade.scene import Scene

#: Camera pixels along each side of the sensor whose rays the picture draws.
BUNDLE_GRID = 12
#: The camera's frustum is drawn this share of the station's extent long.
FRUSTUM_SHARE = 1.0 / 8.0
#: The surface patch around the dent spans this share of the station's extent.
PATCH_SHARE = 1.0 / 8.0
#: Colours of the picture.
SEEN, MISSED, CAMERA, SCREEN, PART, DENT = "tab:blue", "0.65", "black", "tab:green", "0.55", "red"


def add(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "station",
        help="draw the station (camera, screen, part) and print its geometry",
        description="Draw a scene's station in the world frame (the camera's frustum, the "
        "screen's outline, the part around the dent, a bundle of camera rays reflected onto "
        "the screen) and print its numbers: working distance, incidence at the dent, where "
        "the reflected chief ray lands on the screen, the share of the screen the camera sees "
        "and the screen per camera pixel (docs/stations.md). A scene whose screen no camera "
        "pixel sees, or sees from behind, is refused. Without a scene file: the paper's rig.",
    )
    add_scene_flags(p, device=False)
    p.add_argument(
        "-o",
        "--out",
        type=path_arg,
        default=Path("station.png"),
        metavar="PNG",
        help="the picture, a PNG (default %(default)s)",
    )
    p.add_argument("--json", action="store_true", help="print the numbers as JSON")


def run(args: argparse.Namespace) -> int:
    from glshade.files import atomic_write_bytes
    from glshade.oracle.station_report import station_report

    scene = scene_from_args(args)
    check_outputs(args, scene, [("-o", args.out, (".png",))])
    report = station_report(scene)
    atomic_write_bytes(args.out, picture(scene, report), "-o")
    save_scene(args, scene)
    if args.json:
        print(json.dumps(report.to_json(), indent=2, ensure_ascii=False))
    else:
        print(f"station: {report.title}")
        for line in report.lines():
            print(f"  {line}")
        print(f"wrote {args.out}")
    return 0


# ============================================================================ the picture
def _plotted(points: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World points (…, 3) as the plot's axes take them: ``(z, x, y)``, so that the world's
    up (``+y``) is the plot's vertical and the axes stay right-handed."""
    p = np.asarray(points, np.float64)
    return p[..., 2], p[..., 0], p[..., 1]


def screen_outline(scene: Scene) -> np.ndarray:
    """The screen's rectangle (5, 3), world mm, closed."""
    plane, (hu, hv) = scene.station.screen, scene.emitter.half_size
    signs = ((-1, -1), (1, -1), (1, 1), (-1, 1), (-1, -1))
    return np.array([plane.centre + a * hu * plane.e_u + b * hv * plane.e_v for a, b in signs])


def frustum(scene: Scene, length: float) -> tuple[np.ndarray, np.ndarray]:
    """The camera's principal point (3,) and the far corners (4, 3) of a frustum ``length``
    mm deep along its axis (world mm), through its corner pixels."""
    cam, pose = scene.camera, scene.station.camera
    corners = []
    for row, col in (
        (0, 0),
        (0, cam.width - 1),
        (cam.height - 1, cam.width - 1),
        (cam.height - 1, 0),
    ):
        _, d = cam.pixel_rays(slice(row, row + 1), slice(col, col + 1), 1, pose=pose)
        d = d[0, 0]
        corners.append(pose.position + d * length / float(d @ pose.forward))
    return np.asarray(pose.position), np.array(corners)


def surface_patch(scene: Scene, half: float, count: int = 25) -> np.ndarray:
    """The defect-free surface around the dent, ``±half`` mm in the part's ``x`` and ``z``:
    (count, count, 3) world mm, NaN outside the surface's domain."""
    from glshade.oracle.tracer import surface_height

    x0, _, z0 = (float(c) for c in scene.active.defect.centre(scene))
    x, z = np.meshgrid(
        np.linspace(x0 - half, x0 + half, count), np.linspace(z0 - half, z0 + half, count)
    )
    y = surface_height(scene.surface, scene.defect, x, z)
    return scene.station.part.to_world_points(np.stack([x, y, z], axis=-1))


def ray_segments(scene: Scene, reach: float) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """The bundle of :data:`BUNDLE_GRID`² camera rays that hit the part, each camera → hit
    → screen's plane (world mm): those that land on the screen and those that do not (drawn
    ``reach`` mm past the hit where the plane is farther or never reached)."""
    from glshade.oracle.station_report import trace_grid

    traced, part = trace_grid(scene, BUNDLE_GRID), scene.station.part
    origin = part.to_world_points(traced.origin)
    hits = part.to_world_points(traced.points[traced.hit])
    ends = part.to_world_points(traced.plane_points[traced.hit])
    short = hits + reach * part.to_world_vectors(traced.reflected[traced.hit])
    far = ~(traced.plane_t[traced.hit] <= reach) & ~traced.on_screen[traced.hit]
    ends = np.where(far[:, None], short, ends)
    seen: list[np.ndarray] = []
    missed: list[np.ndarray] = []
    for hit, end, on in zip(hits, ends, traced.on_screen[traced.hit], strict=True):
        (seen if on else missed).append(np.array([origin, hit, end]))
    return seen, missed


def _extent(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The finite ``points``' (N, 3) lower corner and size, no side below 1 % of the
    largest."""
    finite = points[np.isfinite(points).all(axis=1)]
    low, high = finite.min(axis=0), finite.max(axis=0)
    size = np.maximum(high - low, 0.01 * float((high - low).max()) + 1e-9)
    return low, size


def picture(scene: Scene, report: StationReport) -> bytes:
    """The station drawn (world frame, mm) as PNG bytes (matplotlib's Agg canvas)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    free = scene.without_defect()
    outline = screen_outline(free)
    dent = np.asarray(report.dent_world)
    key = np.vstack([outline, free.station.camera.position, dent])
    scale = float(_extent(key)[1].max())
    fig = Figure(figsize=(8.0, 7.0))
    FigureCanvasAgg(fig)
    ax: Axes3D = fig.add_subplot(projection="3d", computed_zorder=False)
    drawn = _draw(ax, free, report, outline, scale)
    low, size = _extent(drawn)
    pad = 0.04 * size
    for setter, lo, hi in zip(
        (ax.set_xlim, ax.set_ylim, ax.set_zlim),
        _plotted(low - pad),
        _plotted(low + size + pad),
        strict=True,
    ):
        setter(float(lo), float(hi))
    ax.set_box_aspect(tuple(float(s) for s in _plotted(size + 2 * pad)))
    ax.set_xlabel("z (mm)")
    ax.set_ylabel("x (mm)")
    ax.set_zlabel("y (mm), up")
    ax.view_init(elev=18.0, azim=-62.0)
    ax.set_title(
        f"{report.title}\nworking distance {report.working_distance_mm:.1f} mm, "
        f"incidence {report.incidence_deg:.1f}°, screen coverage {100 * report.coverage:.0f} %",
        fontsize=10,
    )
    _legend(ax)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110, bbox_inches="tight")
    return buffer.getvalue()


def _draw(
    ax: Axes3D, scene: Scene, report: StationReport, outline: np.ndarray, scale: float
) -> np.ndarray:
    """Draw the screen, the camera, the part, the dent and the rays; the points (N, 3)
    drawn, for the limits."""
    from mpl_toolkits.mplot3d.art3d import Line3DCollection

    ax.plot(*_plotted(outline), color=SCREEN, lw=1.5, zorder=2)
    patch = surface_patch(scene, 0.5 * PATCH_SHARE * scale)
    if np.isfinite(patch).all():
        ax.plot_surface(*_plotted(patch), color=PART, alpha=0.7, linewidth=0, zorder=1)
    else:
        for line in (*patch, *patch.transpose(1, 0, 2)):
            ax.plot(*_plotted(line), color=PART, lw=0.5, zorder=1)
    seen, missed = ray_segments(scene, 0.6 * scale)
    for segments, colour, width in ((missed, MISSED, 0.4), (seen, SEEN, 0.5)):
        if segments:
            lines = [np.stack(_plotted(s), axis=-1) for s in segments]
            bundle = Line3DCollection(lines, colors=colour, linewidths=width, alpha=0.7)
            bundle.set_zorder(3)
            ax.add_collection3d(bundle)
    apex, corners = frustum(scene, FRUSTUM_SHARE * scale)
    for corner in corners:
        ax.plot(*_plotted(np.array([apex, corner])), color=CAMERA, lw=1.2, zorder=4)
    ax.plot(*_plotted(np.vstack([corners, corners[:1]])), color=CAMERA, lw=1.2, zorder=4)
    dent = np.asarray(report.dent_world)
    ax.scatter(*_plotted(dent[None, :]), color=DENT, s=36, depthshade=False, zorder=5)
    drawn = [outline, apex[None, :], corners, patch.reshape(-1, 3), dent[None, :]]
    drawn += [s.reshape(-1, 3) for s in (*seen, *missed)]
    return np.vstack(drawn)


def _legend(ax: Axes3D) -> None:
    from matplotlib.lines import Line2D

    handles = [
        Line2D([], [], color=CAMERA, lw=1.0, label="camera (frustum)"),
        Line2D([], [], color=SCREEN, lw=1.5, label="screen"),
        Line2D([], [], color=PART, lw=4.0, label="part (around the dent)"),
        Line2D([], [], color=DENT, marker="o", lw=0, label="dent"),
        Line2D([], [], color=SEEN, lw=0.8, label="rays onto the screen"),
        Line2D([], [], color=MISSED, lw=0.8, label="rays that miss it"),
    ]
    ax.legend(handles=handles, loc="upper left", fontsize=8)
