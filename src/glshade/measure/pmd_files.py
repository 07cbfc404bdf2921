"""What a PMD measurement writes: the raw sequence for external decoders (``--frames
DIR``) and the maps behind its numbers with a figure of each (``--maps DIR``).

Every file is written atomically (:mod:`glshade.files`); the directories are checked
before any work (:func:`check_output_dir`)."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from glshade.components.emitter.fringes.table import fringes_of
from glshade.errors import GlshadeError
from glshade.files import atomic_write_bytes, check_output, encode_image, write_npy
from glshade.measure.figures import new_figure, save_figure
from glshade.scene import Scene

#: Frame file formats: 16-bit PNG (the recorded values times 65535) or 32-bit float TIFF.
FRAME_FORMATS = {"png": (".png", 16), "tif": (".tif", 32)}
#: The files ``--maps`` writes (each ``.npy`` beside a ``.png`` figure of it).
MAP_FILES = ("decoded", "modulation", "wrapped_phase", "error_mm", "slopes", "height_um")


def check_output_dir(path: str | os.PathLike[str], what: str) -> Path:
    """A directory results may be written into (made when missing: its parent must
    exist and be writable), or a one-line error naming ``what``."""
    target = Path(path)
    if target.exists() and not target.is_dir():
        raise GlshadeError(f"{what} {path}: is not a directory")
    if not target.exists():
        parent = target.parent if str(target.parent) else Path(".")
        if not parent.is_dir():
            raise GlshadeError(f"{what} {path}: directory {parent} does not exist")
        if not os.access(parent, os.W_OK | os.X_OK):
            raise GlshadeError(f"{what} {path}: directory {parent} is not writable")
    elif not os.access(target, os.W_OK | os.X_OK):
        raise GlshadeError(f"{what} {path}: is not writable")
    return target


def frame_name(index: int, frame, suffix: str) -> str:
    """``frame_007_v_p1_n3.png``: number, direction, period index, shift index."""
    return f"frame_{index:03d}_{frame.direction}_p{frame.period_index}_n{frame.shift_index}{suffix}"


def write_frames(directory: Path, scene: Scene, recorded: np.ndarray, fmt: str = "png") -> Path:
    """The recorded sequence, one image per frame, and ``manifest.json``: the frames in
    order, each ``{file, direction, period_mm, period_index, shift_index, shift_rad}``,
    the coding and the scene (as a scene file's tables). Returns the manifest's path."""
    suffix, bits = FRAME_FORMATS[fmt]
    directory.mkdir(parents=False, exist_ok=True)
    frames = scene.active.emitter.sequence(scene)
    entries = []
    for index, frame in enumerate(frames):
        name = frame_name(index, frame, suffix)
        path = check_output(directory / name, "--frames")
        atomic_write_bytes(path, encode_image(recorded[index], suffix, bits), "--frames")
        entries.append(
            {
                "file": name,
                "direction": frame.direction,
                "period_mm": frame.period_mm,
                "period_index": frame.period_index,
                "shift_index": frame.shift_index,
                "shift_rad": frame.shift_rad,
            }
        )
    em = fringes_of(scene)
    manifest = {
        "format": {"png": "16-bit PNG: recorded value x 65535", "tif": "32-bit float TIFF"}[fmt],
        "units": "recorded: 1 = the sensor's full scale (radiance 1 without a sensor)",
        "coding": {
            "periods_mm": list(em.periods),
            "shifts": em.shifts,
            "directions": list(em.directions),
            "offset": em.offset,
            "amplitude": em.amplitude,
            "gamma": em.gamma,
            "levels": em.levels,
            "screen_half_size_mm": list(em.half_size),
            "phase": "L = offset + amplitude cos(2 pi s / period_mm - shift_rad), s = the screen "
            "coordinate along the direction + half_size (mm from the screen's edge)",
        },
        "frames": entries,
        "scene": scene.to_dict(),
    }
    path = check_output(directory / "manifest.json", "--frames")
    text = json.dumps(manifest, indent=2, default=str) + "\n"
    atomic_write_bytes(path, text.encode(), "--frames")
    return path


def write_maps(directory: Path, scene: Scene, result) -> list[Path]:
    """Each map of a :class:`~glshade.measure.pmd.PmdResult` as ``.npy`` and a ``.png``
    figure with a colour bar (:data:`MAP_FILES`); returns the paths written."""
    directory.mkdir(parents=False, exist_ok=True)
    maps = result.maps
    arrays = {
        "decoded": maps.decoded.astype(np.float32),
        "modulation": maps.modulation,
        "wrapped_phase": maps.wrapped,
        "error_mm": maps.error.astype(np.float32),
        "slopes": maps.slopes_urad,
        "height_um": maps.height_um,
    }
    written = []
    for name, array in arrays.items():
        path = check_output(directory / f"{name}.npy", "--maps")
        write_npy(path, array)
        written.append(path)
    for name, (image, label, cmap, symmetric) in map_images(scene, result).items():
        path = check_output(directory / f"{name}.png", "--maps")
        map_figure(image, label, cmap, symmetric, f"{scene.title()}: {name}", path, result)
        written.append(path)
    return written


def map_images(scene: Scene, result) -> dict[str, tuple[np.ndarray, str, str, bool]]:
    """What each figure shows: ``name -> (image, colour bar label, colour map, symmetric
    about 0)``; the first coded direction's finest period for the phase and modulation."""
    maps = result.maps
    direction = fringes_of(scene).directions[0]
    finest = fringes_of(scene).periods[0]
    axes = [0 if d == "u" else 1 for d in fringes_of(scene).directions]
    error = np.linalg.norm(maps.error[..., axes], axis=-1) * 1e3
    slope = np.hypot(maps.slopes_urad[..., 0], maps.slopes_urad[..., 1])
    return {
        "wrapped_phase": (
            maps.wrapped[0, 0],
            f"wrapped phase, {finest:g} mm fringes along {direction} (rad)",
            "twilight",
            False,
        ),
        "modulation": (
            maps.modulation[0, 0],
            f"modulation B of the {finest:g} mm fringes (recorded units)",
            "viridis",
            False,
        ),
        "error_mm": (error, "|decoded - exact| (µm on the screen)", "magma", False),
        "slopes": (slope, "slope deviation |∇d| (µrad)", "magma", False),
        "height_um": (maps.height_um, "reconstructed height (µm)", "RdBu_r", True),
        "decoded": (
            maps.decoded[..., axes[0]],
            f"decoded {'uv'[axes[0]]} (mm on the screen)",
            "cividis",
            False,
        ),
    }


def map_figure(
    image: np.ndarray, label: str, cmap: str, symmetric: bool, title: str, path: Path, result
) -> None:
    """One map with a colour bar in its unit; NaN (no valid decode) drawn grey. The title
    carries the case's status when its numbers cannot be read."""
    fig = new_figure(6.4, 5.4)
    ax = fig.add_subplot(1, 1, 1)
    finite = image[np.isfinite(image)]
    lo, hi = np.percentile(finite, [0.5, 99.5]) if finite.size else (0.0, 1.0)
    if symmetric:
        top = max(abs(lo), abs(hi)) or 1.0
        lo, hi = -top, top
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        hi = lo + 1.0
    from matplotlib import colormaps

    colours = colormaps[cmap].with_extremes(bad=(0.75, 0.75, 0.75))
    shown = ax.imshow(image, cmap=colours, vmin=lo, vmax=hi, interpolation="nearest")
    bar = fig.colorbar(shown, ax=ax, shrink=0.85)
    bar.set_label(label)
    height, width = image.shape
    ax.set_xlabel(f"column (of {width} px)")
    ax.set_ylabel(f"row (of {height} px)")
    if result.status != "ok":
        title = f"{title} [{result.status}: not measurable]"
    ax.set_title(title, fontsize=9)
    save_figure(fig, path)
