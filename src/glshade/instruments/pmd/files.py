"""What a PMD measurement writes: the raw sequence for external decoders (``--frames
DIR``) and the maps behind its numbers with a figure of each (``--maps DIR``).

Every file is written atomically (:mod:`glshade.files`); the directories are checked
before any work (:func:`check_output_dir`). A ``--frames`` folder holds exactly the
manifest's frames afterwards: the frames an earlier run wrote there under glshade's names
and this run does not write are removed (regular files inside the folder only)."""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from glshade.components.emitter.fringes.table import FringeFrame, fringes_of
from glshade.errors import GlshadeError
from glshade.files import (
    atomic_write_bytes,
    check_inside,
    check_output,
    encode_image,
    probe_directory,
    remove_inside,
    write_npy,
)
from glshade.instruments.figures import new_figure, save_figure
from glshade.scene import Scene

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.colors import Colormap
    from matplotlib.figure import Figure
    from matplotlib.image import AxesImage

    from glshade.instruments.pmd.reconstruct import Heights
    from glshade.instruments.pmd.station import PmdResult

#: A window of an image: first row, last row, first column, last column.
Box = tuple[int, int, int, int]

#: Frame file formats: 16-bit PNG (the recorded values times 65535) or 32-bit float TIFF.
FRAME_FORMATS = {"png": (".png", 16), "tif": (".tif", 32)}
#: How a frame file holds the recorded value, by format (the manifest's ``format``).
FRAME_ENCODING = {
    "png": "16-bit greyscale PNG: recorded value = pixel value / 65535",
    "tif": "32-bit float greyscale TIFF: recorded value = pixel value",
}
#: The files ``--maps`` writes with a ``.png`` figure of each.
MAP_FILES = (
    "decoded",
    "modulation",
    "modulation_share",
    "wrapped_phase",
    "error_mm",
    "slopes",
    "height_um",
)
#: The files ``--maps`` writes without a figure: what the numbers are recomputed from.
DATA_FILES = (
    "exact",
    "exact_defect_free",
    "decoded_defect_free",
    "decoded_twin",
    "region",
    "shift_pixels",
    "noise_pixels",
)
#: The screen's white, recorded like the frames (``frame_white.png``).
WHITE_FRAME = "frame_white"
#: The frame files glshade names in a ``--frames`` folder (what a rerun may remove).
FRAME_FILE = re.compile(r"frame_(?:\d{3,}_[uv]_p\d+_n\d+|white)\.(?:png|tif)")


def check_output_dir(
    path: str | os.PathLike[str], what: str, inputs: tuple[Path, ...] = ()
) -> Path:
    """A directory results may be written into (made when missing: its parent must
    exist and be writable, proven by a probe before any work), or a one-line error naming
    ``what``; it must not hold one of the run's ``inputs`` under a name glshade writes
    there (a height map called ``decoded.npy``), and a file of such a name (which the run
    replaces or removes) must be a regular file inside it, not a link."""
    target = Path(path)
    if target.exists() and not target.is_dir():
        raise GlshadeError(f"{what} {path}: is not a directory")
    if not target.exists():
        parent = target.parent if str(target.parent) else Path(".")
        if not parent.is_dir():
            raise GlshadeError(f"{what} {path}: directory {parent} does not exist")
        if not os.access(parent, os.W_OK | os.X_OK):
            raise GlshadeError(f"{what} {path}: directory {parent} is not writable")
        probe_directory(parent, what, os.fspath(path))  # before the work, not after it
        return target
    if not os.access(target, os.W_OK | os.X_OK):
        raise GlshadeError(f"{what} {path}: is not writable")
    probe_directory(target, what, os.fspath(path), os.fspath(path))  # /proc/self/fd: W_OK
    for entry in os.scandir(target):
        if not _written_name(entry.name):
            continue
        if entry.is_symlink():  # written through, it would replace what it leads to
            raise GlshadeError(
                f"{what} {path}: {entry.name} is a symbolic link; glshade replaces or "
                "removes an earlier run's files there, never through a link: remove it "
                "or choose another directory"
            )
        # what the run would replace: a regular file inside, none of the run's inputs
        check_output(entry.path, what, probe=False, inputs=inputs)
        check_inside(target, Path(entry.path), what)
    return target


def _written_name(name: str) -> bool:
    """Whether a PMD run writes a file of this name in its ``--maps`` or ``--frames``."""
    return (
        name == "manifest.json"
        or name.startswith("frame_")
        or any(name in (f"{m}.npy", f"{m}.png") for m in MAP_FILES)
        or name in (f"{m}.npy" for m in DATA_FILES)
    )


def frame_entry(index: int, frame: FringeFrame, name: str) -> dict[str, Any]:
    """A frame's entry in a frames folder's manifest: its file and what it shows."""
    return {
        "file": name,
        "index": index,
        "direction": frame.direction,
        "period_mm": frame.period_mm,
        "period_index": frame.period_index,
        "shift_index": frame.shift_index,
        "shift_rad": frame.shift_rad,
    }


def frame_name(index: int, frame: FringeFrame, suffix: str) -> str:
    """``frame_007_v_p1_n3.png``: number, direction, period index, shift index."""
    return f"frame_{index:03d}_{frame.direction}_p{frame.period_index}_n{frame.shift_index}{suffix}"


def write_frames(directory: Path, scene: Scene, result: PmdResult, fmt: str = "png") -> Path:
    """The recorded sequence of a :class:`~glshade.instruments.pmd.station.PmdResult`, one image per
    frame in the order shown, the screen's white recorded alike (``frame_white``), and
    ``manifest.json``: all a decoder needs (:func:`frames_manifest`). The frames of an
    earlier run that this one does not write are removed, and the old manifest first (an
    interrupted run leaves no manifest naming another run's frames). Returns the
    manifest's path."""
    maps = result.maps
    sequence = scene.active.emitter.sequence(scene)
    if len(maps.recorded) < len(sequence):
        raise GlshadeError(
            "--frames: this result was measured without its frames kept "
            "(measure_pmd_scene(..., keep_frames=True))"
        )
    suffix, bits = FRAME_FORMATS[fmt]
    directory.mkdir(parents=False, exist_ok=True)
    remove_inside(directory, directory / "manifest.json")
    entries = []
    for index, frame in enumerate(sequence):
        name = frame_name(index, frame, suffix)
        _write_frame(directory / name, maps.recorded[index], suffix, bits)
        entries.append(frame_entry(index, frame, name))
    white = WHITE_FRAME + suffix
    _write_frame(directory / white, maps.recording.white, suffix, bits)
    manifest = frames_manifest(scene, result, fmt, entries, white)
    path = directory / "manifest.json"
    text = json.dumps(manifest, indent=2, default=str) + "\n"
    atomic_write_bytes(path, text.encode(), "--frames", within=directory)
    _remove_stale_frames(directory, {entry["file"] for entry in entries} | {white})
    return path


def _write_frame(path: Path, image: np.ndarray, suffix: str, bits: int) -> None:
    atomic_write_bytes(path, encode_image(image, suffix, bits), "--frames", within=path.parent)


def _remove_stale_frames(directory: Path, keep: set[str]) -> None:
    """Remove the regular files of ``directory`` glshade names as frames
    (:data:`FRAME_FILE`) that are not in ``keep``: an earlier run's."""
    for entry in os.scandir(directory):
        if FRAME_FILE.fullmatch(entry.name) and entry.name not in keep:
            remove_inside(directory, Path(entry.path))


def frames_manifest(
    scene: Scene, result: PmdResult, fmt: str, entries: list[dict[str, Any]], white: str
) -> dict[str, Any]:
    """What decoding the written frames takes, with nothing else known: the files'
    encoding and units, the sensor and its black level, the exposure applied, the white
    frame and the response the validity threshold is based on, the threshold's rule and
    value, the coding, the directions' order and the scene."""
    em, rec = fringes_of(scene), result.maps.recording
    return {
        "format": FRAME_ENCODING[fmt],
        "units": "recorded units: 1 = the sensor's full scale, the sensor's black level "
        "included (without a sensor: radiance, 1 = the screen's white seen in a perfect "
        "mirror)",
        "sensor": _sensor_entry(scene),
        "sensor_black_level": rec.black_level,
        "exposure": {
            "camera_exposure": scene.camera.exposure,
            "gain": rec.gain,
            "rule": "recorded = sensor_black_level + (1 - sensor_black_level) x gain x "
            "radiance, before the sensor's noise, clipping to [0, 1] and rounding (without a "
            "sensor: recorded = radiance)",
        },
        "white": {
            "file": white,
            "response": rec.white_response,
            "rule": "response = the brightest pixel's noise-free response to the screen's white "
            "above the sensor's black level, in recorded units: (1 - sensor_black_level) x "
            "min(gain x radiance, 1); the file is that white as recorded, noise and black "
            "level in it",
        },
        "validity": {
            "modulation_share": rec.modulation_share,
            "min_modulation": rec.threshold,
            "rule": "a pixel is valid where every frame is finite and, in every coded "
            "direction, every period's modulation B = (2 / N) |sum_n I_n exp(i shift_rad_n)| "
            "(recorded units) is at least min_modulation = modulation_share x "
            "coding.amplitude x white.response (min_modulation alone where "
            "modulation_share is null: given as such)",
        },
        "coding": em.codec.to_dict(),
        "frames": entries,
        "scene": scene.to_dict(),
    }


def _sensor_entry(scene: Scene) -> dict[str, Any] | None:
    """The sensor as it recorded (None without one), its black level worked out."""
    if not scene.active.records(scene):
        return None
    sensor = scene.sensor
    return {
        "full_well_e": sensor.full_well_e,
        "read_noise_e": sensor.read_noise_e,
        "bit_depth": sensor.bit_depth,
        "black_level_dn": sensor.black_dn,
        "black_level": sensor.black_level,
        "full_scale_dn": sensor.full_scale_dn,
    }


def write_maps(directory: Path, scene: Scene, result: PmdResult) -> list[Path]:
    """Each map of a :class:`~glshade.instruments.pmd.station.PmdResult` as ``.npy``
    (:data:`MAP_FILES` with a ``.png`` figure, :data:`DATA_FILES` without); returns the
    paths written."""
    directory.mkdir(parents=False, exist_ok=True)
    maps = result.maps
    arrays = {
        "decoded": maps.decoded,
        "modulation": maps.modulation,
        "modulation_share": maps.modulation_share,
        "wrapped_phase": maps.wrapped,
        "error_mm": maps.error,
        "slopes": maps.slopes_urad,
        "height_um": maps.height_um,
        "exact": maps.exact,
        "exact_defect_free": maps.exact_defect_free,
        "decoded_defect_free": maps.decoded_defect_free,
        "decoded_twin": maps.decoded_twin,
        "region": maps.region,
        "shift_pixels": maps.shift_pixels,
        "noise_pixels": maps.noise_pixels,
    }
    written = []
    for name, array in arrays.items():
        path = directory / f"{name}.npy"
        write_npy(path, array, within=directory)
        written.append(path)
    for name, shown in map_images(scene, result).items():
        path = directory / f"{name}.png"
        map_figure(shown, scene, result, path)
        written.append(path)
    return written


# --------------------------------------------------------------------------- figures
#: How a figure's colour scale is set: ``cyclic`` 0 to 2π; ``symmetric`` about 0 (a
#: signed quantity: ±the largest magnitude, or its 99.5th percentile when ``robust``);
#: ``magnitude`` 0 to the largest value (the dent's own peak always on the scale);
#: ``range`` the smallest to the largest value.
SCALES = ("cyclic", "symmetric", "magnitude", "range")
#: The colour of a pixel with no value.
NO_VALUE = (0.75, 0.75, 0.75)


@dataclass(frozen=True)
class MapView:
    """What one figure shows: ``title`` (the map in words), ``panels`` (a title and an
    image-aligned map each, on one colour scale), the colour bar's ``label`` (with its
    unit), ``cmap``, ``scale`` (one of :data:`SCALES`), ``robust`` (a symmetric scale
    from the 99.5th percentile: unwrapping failures would swamp it), ``no_value`` (what
    a grey pixel means) and ``zoom``: ``window`` adds the dent's window of the first
    panel, ``grid`` the heights on their ``(x, z)`` grid, ``none`` nothing."""

    title: str
    panels: tuple[tuple[str, np.ndarray], ...]
    label: str
    cmap: str
    scale: str
    no_value: str = "not decoded (modulation too low, or no screen seen)"
    robust: bool = False
    zoom: str = "window"


def map_images(scene: Scene, result: PmdResult) -> dict[str, MapView]:
    """What each figure shows (:class:`MapView`, by file name): the first coded
    direction's finest period for the phase and the modulation, every coded coordinate
    for the error."""
    maps, em = result.maps, fringes_of(scene)
    finest, direction = em.periods[0], em.directions[0]
    axes = [0 if d == "u" else 1 for d in em.directions]
    first = axes[0]  # the first coded direction's layer (the layers are in (u, v) order)
    frame = f"the image, {scene.camera.width}x{scene.camera.height} px"
    slope = np.hypot(maps.slopes_urad[..., 0], maps.slopes_urad[..., 1])
    records = "recorded units, full scale 1" if scene.active.records(scene) else "radiance"
    return {
        "wrapped_phase": MapView(
            f"wrapped phase of the {finest:g} mm fringes along {direction}",
            ((frame, decoded_only(maps.wrapped[first, 0], maps.decoded)),),
            "wrapped phase (rad)", "twilight", "cyclic",
        ),
        "modulation": MapView(
            f"modulation B of the {finest:g} mm fringes along {direction}",
            ((frame, maps.modulation[first, 0]),),
            f"modulation B ({records})", "viridis", "magnitude",
            no_value="no screen seen",
        ),
        "modulation_share": MapView(
            f"modulation share B / (b1 W) of the {finest:g} mm fringes along {direction}, "
            "noise-free",
            ((frame, maps.modulation_share[first]),),
            "modulation share (1: a sharp mirror)", "viridis", "magnitude",
            no_value="no screen seen",
        ),
        "error_mm": MapView(
            "decoding error: decoded - exact screen point",
            tuple((f"along {'uv'[a]}, {frame}", 1e3 * maps.error[..., a]) for a in axes),
            "decoded - exact (µm on the screen)", "RdBu_r", "symmetric",
            robust=True, zoom="none",
        ),
        "slopes": MapView(
            "slope deviation |∇d| from the nominal surface",
            ((frame, slope),),
            "slope deviation |∇d| (µrad)", "magma", "magnitude",
        ),
        "height_um": MapView(
            "reconstructed height (slopes integrated)",
            ((frame, maps.height_um),),
            "height (µm)", "RdBu_r", "symmetric",
            no_value="outside the height grid, or not decoded", zoom="grid",
        ),
        "decoded": MapView(
            f"decoded screen coordinate {'uv'[axes[0]]}",
            ((frame, maps.decoded[..., axes[0]]),),
            f"decoded {'uv'[axes[0]]} (mm on the screen)", "cividis", "range", zoom="none",
        ),
    }  # fmt: skip


def decoded_only(values: np.ndarray, decoded: np.ndarray) -> np.ndarray:
    """``values`` (H, W) with NaN where the pixel has no valid decode (``decoded``: the
    decoded screen points, NaN there): a wrapped phase of no signal reads 0."""
    return np.where(np.isfinite(decoded).any(axis=-1), values, np.nan)


def dent_box(scene: Scene, shape: tuple[int, int]) -> Box | None:
    """The dent's window in the image (first row, last row, first column, last column),
    None where the dent is not in the frame or its window fills most of it (a zoom
    would show nothing new)."""
    from glshade.metrics.status import dent_window

    window = dent_window(scene, shape)
    rows, cols = np.flatnonzero(window.any(axis=1)), np.flatnonzero(window.any(axis=0))
    if not rows.size:
        return None
    box = (int(rows[0]), int(rows[-1]), int(cols[0]), int(cols[-1]))
    if rows.size > 0.7 * shape[0] and cols.size > 0.7 * shape[1]:
        return None
    return box


def map_scale(shown: MapView, values: np.ndarray, box: Box | None) -> tuple[float, float]:
    """The colour scale ``(lo, hi)`` of a figure over all its ``values`` (the finite
    ones), per :data:`SCALES`; ``box``: the dent's window (its peak stays on a magnitude
    scale however an outlier elsewhere clips the rest)."""
    finite = values[np.isfinite(values)]
    if shown.scale == "cyclic":
        return 0.0, 2.0 * math.pi
    if not finite.size:
        return (-1.0, 1.0) if shown.scale == "symmetric" else (0.0, 1.0)
    if shown.scale == "symmetric":
        top = float(np.percentile(np.abs(finite), 99.5) if shown.robust else np.abs(finite).max())
        return -(top or 1.0), top or 1.0
    if shown.scale == "magnitude":
        top = float(np.percentile(finite, 99.9))
        if box is not None:
            r0, r1, c0, c1 = box
            near = shown.panels[0][1][r0 : r1 + 1, c0 : c1 + 1]
            top = max(top, float(np.nanmax(near)) if np.isfinite(near).any() else 0.0)
        return 0.0, top or 1.0
    lo, hi = float(finite.min()), float(finite.max())
    return (lo, hi) if hi > lo else (lo, lo + 1.0)


def map_figure(shown: MapView, scene: Scene, result: PmdResult, path: Path) -> tuple[float, float]:
    """One figure: the map's panels (and the dent's window or the height grid beside
    them) on one colour scale with a colour bar in its unit, grey where there is no
    value (said under the figure), the case and the map in the title, which carries the
    case's status when its numbers cannot be read. Returns the colour scale drawn."""
    box = dent_box(scene, shown.panels[0][1].shape) if shown.zoom == "window" else None
    count = len(shown.panels) + (box is not None or shown.zoom == "grid")
    fig = new_figure(0.6 + 4.6 * count, 4.9)
    fig.set_layout_engine("constrained")
    axes = [fig.add_subplot(1, count, i + 1) for i in range(count)]
    everything = [image for _, image in shown.panels]
    if shown.zoom == "grid":
        everything.append(result.maps.heights.height_um)
    values = np.concatenate([np.ravel(a) for a in everything])
    lo, hi = map_scale(shown, values, box)
    style = {"cmap": _colours(shown.cmap), "vmin": lo, "vmax": hi, "interpolation": "nearest"}
    for ax, (title, image) in zip(axes, shown.panels, strict=False):
        picture = _pixels(ax, image, title, style)
    if box is not None:
        _window(axes[0], axes[-1], shown.panels[0][1], box, style)
    if shown.zoom == "grid":
        _grid(axes[-1], result.maps.heights, style)
    _colour_bar(fig, axes, picture, shown, values)
    status = "" if result.status == "ok" else f"  [{result.status}: not measurable]"
    fig.suptitle(f"PMD: {shown.title}\n{scene.title()}{status}", fontsize=10)
    if not np.isfinite(values).all():
        fig.text(0.01, -0.01, f"grey: no value, {shown.no_value}", fontsize=8, va="top")
    save_figure(fig, path, within=path.parent)
    return lo, hi


def _colours(cmap: str) -> Colormap:
    from matplotlib import colormaps

    return colormaps[cmap].with_extremes(bad=NO_VALUE)


def _pixels(ax: Axes, image: np.ndarray, title: str, style: dict[str, Any]) -> AxesImage:
    """A map over the whole frame, in pixel coordinates."""
    shown = ax.imshow(image, **style)
    ax.set_xlabel("column (px)")
    ax.set_ylabel("row (px)")
    ax.set_title(title, fontsize=9)
    return shown


def _window(full: Axes, ax: Axes, image: np.ndarray, box: Box, style: dict[str, Any]) -> None:
    """The dent's window of ``image`` in ``ax`` (its pixel coordinates kept), outlined in
    the full frame."""
    from matplotlib.patches import Rectangle

    r0, r1, c0, c1 = box
    extent = (c0 - 0.5, c1 + 0.5, r1 + 0.5, r0 - 0.5)
    ax.imshow(image[r0 : r1 + 1, c0 : c1 + 1], extent=extent, **style)
    corner, size = (c0 - 0.5, r0 - 0.5), (c1 - c0 + 1, r1 - r0 + 1)
    dashed = Rectangle(corner, *size, fill=False, edgecolor="#00d5ff", linestyle="--", lw=1.2)
    full.add_patch(dashed)
    ax.set_xlabel("column (px)")
    ax.set_ylabel("row (px)")
    ax.set_title(f"the dent's window (dashed), rows {r0}-{r1}, columns {c0}-{c1}", fontsize=9)


def _grid(ax: Axes, heights: Heights, style: dict[str, Any]) -> None:
    """The heights on their regular ``(x, z)`` grid on the surface (mm), with the
    fitted dent."""
    x, z = heights.grid.x, heights.grid.z
    dx, dz = heights.grid.spacing
    extent = (x[0] - dx / 2, x[-1] + dx / 2, z[0] - dz / 2, z[-1] + dz / 2)
    ax.imshow(heights.height_um, origin="lower", extent=extent, **style)
    ax.set_xlabel("x on the surface (mm)")
    ax.set_ylabel("z on the surface (mm)")
    dent = heights.dent
    fit = "no dent fitted" if dent is None else (
        f"fit: depth {dent.depth:.3g} µm, σ {dent.sigma_mm:.3g} mm"
    )  # fmt: skip
    ax.set_title(f"on the surface grid ({len(x)}x{len(z)}); {fit}", fontsize=9)


def _colour_bar(
    fig: Figure, axes: list[Axes], picture: AxesImage, shown: MapView, values: np.ndarray
) -> None:
    """The colour bar of the figure's scale, with arrows where values lie beyond it."""
    finite = values[np.isfinite(values)]
    lo, hi = picture.get_clim()
    below = bool(finite.size and finite.min() < lo - 1e-12 * abs(lo))
    above = bool(finite.size and finite.max() > hi + 1e-12 * abs(hi))
    extend = {(0, 0): "neither", (1, 0): "min", (0, 1): "max", (1, 1): "both"}
    bar = fig.colorbar(picture, ax=axes, shrink=0.9, extend=extend[below, above])
    bar.set_label(shown.label)
    if shown.scale == "cyclic":
        bar.set_ticks([0, math.pi / 2, math.pi, 1.5 * math.pi, 2 * math.pi])
        bar.set_ticklabels(["0", "π/2", "π", "3π/2", "2π"])
