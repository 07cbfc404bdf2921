"""Reading height maps: measured topographies and sampled CAD patches (SPEC §8.1).

A height map is ``heights[row, column]`` in mm, rows along +z and columns along +x
(``docs/scene-format.md``, *Height maps*). Formats, by extension:

- ``.npy``: any real integer or float array (``allow_pickle=False``), times ``scale``;
- ``.x3p`` (ISO 25178-72, read with ``x3pio``): heights and the grid spacing in metres
  (converted to mm; ``scale`` does not apply); its x axis is our x (columns), its y axis
  our z (rows); only regular grids;
- ``.tif``/``.tiff`` (``tifffile``): a 2-D float or unsigned integer image, times ``scale``;
- ``.png``: 16-bit greyscale only (OpenCV), times ``scale``.

Every problem is a :class:`SceneError` of one line naming ``surface.file``. Maps are
cached by path, modification time and size: an edited file is read again.
"""

from __future__ import annotations

import functools
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from glshade.errors import SceneError

FIELD = "surface.file"
SUFFIXES = (".npy", ".x3p", ".tif", ".tiff", ".png")
MIN_SIDE = 4
#: The largest side accepted (the renderer's texture limit on most GPUs).
MAX_SIDE = 16384


@dataclass(frozen=True, eq=False)
class HeightMap:
    """``heights`` (float64, mm, (rows, columns)); ``spacing_mm``: (along x, along z) when
    the file carries it; ``source``: the path read."""

    heights: np.ndarray = field(repr=False)
    spacing_mm: tuple[float, float] | None
    source: str


def cached_height_map(path: str | os.PathLike[str], scale: float = 1.0) -> HeightMap:
    """:func:`read_height_map`, read again only when the file changed."""
    try:
        st = os.stat(path)
        key = (st.st_mtime_ns, st.st_size)
    except OSError:
        key = (0, 0)
    return _cached(os.fspath(path), key, float(scale))


@functools.lru_cache(maxsize=8)
def _cached(path: str, key: tuple[int, int], scale: float) -> HeightMap:
    return read_height_map(path, scale)


def read_height_map(path: str | os.PathLike[str], scale: float = 1.0) -> HeightMap:
    """The height map in ``path`` (see the module docstring)."""
    path = Path(path)
    name = path.name
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise SceneError(FIELD, f"a height map file ({', '.join(SUFFIXES)})", str(path))
    if path.is_dir():
        raise SceneError(FIELD, "a height map file, not a directory", str(path))
    if not path.is_file():
        raise SceneError(FIELD, "an existing height map file", str(path))
    reader = {".npy": _npy, ".x3p": _x3p, ".tif": _tiff, ".tiff": _tiff, ".png": _png}[suffix]
    try:
        heights, spacing = reader(path)
    except SceneError:
        raise
    except (OSError, ValueError, KeyError, TypeError, RuntimeError, EOFError) as exc:
        raise SceneError(FIELD, f"a readable height map ({name}: {' '.join(str(exc).split())[:120]})") from None
    except Exception as exc:  # the readers' own errors (x3pio, tifffile) have no common base
        raise SceneError(FIELD, f"a readable height map ({name}: {type(exc).__name__}: "
                                f"{' '.join(str(exc).split())[:120]})") from None
    heights = _checked(np.asarray(heights), name)
    if suffix != ".x3p":
        heights = heights * scale
    return HeightMap(heights, spacing, str(path))


def _checked(heights: np.ndarray, name: str) -> np.ndarray:
    if heights.dtype.kind not in "iuf" or heights.dtype.names is not None:
        raise SceneError(FIELD, f"a map of real numbers ({name} holds {heights.dtype})")
    if heights.ndim != 2:
        raise SceneError(FIELD, f"a 2-D map ({name} has shape {heights.shape})")
    rows, cols = heights.shape
    if min(rows, cols) < MIN_SIDE:
        raise SceneError(FIELD, f"a map of at least {MIN_SIDE} x {MIN_SIDE} samples ({name} has {rows} x {cols})")
    if max(rows, cols) > MAX_SIDE:
        raise SceneError(FIELD, f"a map of at most {MAX_SIDE} samples a side ({name} has {rows} x {cols})")
    heights = heights.astype(np.float64)
    bad = ~np.isfinite(heights)
    if bad.any():
        row, col = np.argwhere(bad)[0]
        raise SceneError(FIELD, f"a map of finite heights ({name} has {int(bad.sum())} NaN or Inf samples, the first "
                                f"at row {row}, column {col})")
    return heights


def _npy(path: Path):
    return np.load(path, allow_pickle=False), None


def _x3p(path: Path):
    import x3pio

    x3p = x3pio.read(path)
    if not x3p.layers:
        raise SceneError(FIELD, f"an x3p file with a surface layer ({path.name} has none)")
    layer = x3p.layers[0]
    header = x3p.header
    if type(x3p).__name__ != "Surface" or not layer.is_regular_grid:
        raise SceneError(FIELD, f"an x3p surface on a regular grid ({path.name} is a {type(x3p).__name__.lower()} "
                                "or a non-regular grid)")
    dx, dy = float(header.x.increment), float(header.y.increment)
    if not (dx > 0 and dy > 0):
        raise SceneError(FIELD, f"an x3p file with positive increments ({path.name}: {dx:g}, {dy:g} m)")
    return np.asarray(layer.z, dtype=np.float64) * 1e3, (dx * 1e3, dy * 1e3)


def _tiff(path: Path):
    import tifffile

    image = tifffile.imread(path)
    if image.dtype.kind not in "uf":
        raise SceneError(FIELD, f"a float or unsigned integer TIFF ({path.name} holds {image.dtype})")
    return image, None


def _png(path: Path):
    import cv2

    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise SceneError(FIELD, f"a readable PNG ({path.name})")
    if image.dtype != np.uint16 or image.ndim != 2:
        raise SceneError(FIELD, f"a 16-bit greyscale PNG ({path.name} is {image.dtype.itemsize * 8}-bit with "
                                f"{1 if image.ndim == 2 else image.shape[2]} channels)")
    return image, None
