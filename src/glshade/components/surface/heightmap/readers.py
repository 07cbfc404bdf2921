"""Reading height maps: measured topographies and sampled CAD patches.

Layout
    A height map is ``heights[row, column]``, float64, in mm: rows run along +z and columns
    along +x (``docs/scene-format.md``, *Height maps*). ``spacing_mm`` is ``(along x, along
    z)``, i.e. (between columns, between rows), when the file carries it.

Formats, chosen by the extension (any case):

- ``.npy``: any real integer or float array (``allow_pickle=False``), times ``scale`` mm per
  stored unit; bool, complex, object and structured arrays are refused. No spacing.
- ``.x3p`` (ISO 25178-72, read with ``x3pio``): heights and increments are stored in metres
  and converted to mm, so ``scale`` does not apply. The x3p x axis is our x (columns) and
  its y axis our z (rows): x3pio gives ``layer.z`` shaped ``(SizeY, SizeX)``, x varying
  fastest as the standard stores it, so no transpose is needed. Only the first layer of a
  surface on a regular grid (incremental x and y axes) with positive increments is
  accepted; unmeasured points (NaN) are kept as NaN, like NaN in any other format.
- ``.tif``/``.tiff`` (``tifffile``): a 2-D greyscale image of 32- or 64-bit floats or
  unsigned integers, times ``scale``. No spacing.
- ``.png`` (OpenCV): 16-bit greyscale only, times ``scale``. No spacing.

Every map needs at least :data:`MIN_SIDE` and at most :data:`MAX_SIDE` samples along each
side, and no infinite values. NaN marks an unmeasured sample (the surface component masks
or fills them: its ``fill``); a map needs at least one measured sample. Every problem is a
:class:`~glshade.errors.SceneError` of one line for ``surface.file`` that names the file
and what is wrong.

:func:`cached_height_map` keeps the last few maps, keyed by path, modification time and
size, so an edited file is read again; the arrays it hands out are read-only because they
are shared.
"""

from __future__ import annotations

import functools
import math
import os
import struct
import tokenize
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from glshade.errors import SceneError

FIELD = "surface.file"
SUFFIXES = (".npy", ".x3p", ".tif", ".tiff", ".png")
#: The fewest samples along a side (the bicubic spline needs a 4 x 4 block).
MIN_SIDE = 4
#: The most samples along a side (the renderer's texture limit on most GPUs).
MAX_SIDE = 16384

# What the readers raise on a damaged file besides their own error classes (found by
# feeding them truncated and bit-flipped files): numpy's header parser lets TokenError
# through, tifffile ZeroDivisionError, struct.error and zlib.error, and a damaged header
# can ask for an impossible allocation.
_DAMAGED = (
    OSError,
    ValueError,
    TypeError,
    KeyError,
    IndexError,
    EOFError,
    RuntimeError,
    ArithmeticError,
    MemoryError,
    struct.error,
    zlib.error,
    tokenize.TokenError,
)


@dataclass(frozen=True, eq=False)
class HeightMap:
    """A height map as read from ``source``.

    ``heights``: float64, (rows, columns), mm, rows along +z and columns along +x.
    ``spacing_mm``: (along x, along z) in mm when the file carries it (.x3p), else ``None``.
    ``source``: the path as given. Equality and hashing are by identity (``eq=False``): two
    reads of one file are two maps, and the array is never compared.
    """

    heights: np.ndarray = field(repr=False)
    spacing_mm: tuple[float, float] | None
    source: str


def read_height_map(path: str | os.PathLike[str], scale: float = 1.0) -> HeightMap:
    """The height map in ``path``; ``scale``: mm of height per stored unit (not for .x3p)."""
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
    except _DAMAGED + _library_errors(suffix) as exc:
        detail = " ".join(str(exc).split())[:120] or "no detail"
        raise SceneError(
            FIELD, f"a readable height map ({name}: {type(exc).__name__}: {detail})"
        ) from None
    heights = _checked(np.asarray(heights), name)
    if suffix != ".x3p":
        heights = _scaled(heights, scale, name)
    heights.flags.writeable = False
    return HeightMap(heights, spacing, str(path))


@functools.lru_cache(maxsize=8)
def load_height_map(path_str: str, mtime_ns: int, size: int, scale: float) -> HeightMap:
    """:func:`read_height_map`, cached on the path and the file's modification time and size
    (which only serve as the key)."""
    return read_height_map(path_str, scale)


def cached_height_map(path: str | os.PathLike[str], scale: float = 1.0) -> HeightMap:
    """:func:`read_height_map`, read again only when the file changed."""
    path_str = os.fspath(path)
    try:
        st = os.stat(path_str)
    except OSError:
        return read_height_map(path_str, scale)  # names the problem; nothing to cache
    return load_height_map(path_str, st.st_mtime_ns, st.st_size, float(scale))


def _library_errors(suffix: str) -> tuple[type[BaseException], ...]:
    if suffix == ".x3p":
        import x3pio

        return (x3pio.X3pError,)
    if suffix in (".tif", ".tiff"):
        import tifffile

        return (tifffile.TiffFileError,)
    if suffix == ".png":
        import cv2

        return (cv2.error,)
    return ()


def _check_kind(dtype: np.dtype, name: str) -> None:
    if dtype.kind not in "iuf" or dtype.names is not None or dtype.subdtype is not None:
        raise SceneError(FIELD, f"a map of real integers or floats ({name} holds {dtype})")


def _check_shape(shape: tuple[int, ...], name: str) -> None:
    if len(shape) != 2:
        raise SceneError(FIELD, f"a 2-D map, rows x columns ({name} has shape {tuple(shape)})")
    rows, cols = shape
    if min(rows, cols) < MIN_SIDE:
        raise SceneError(
            FIELD,
            f"a map of at least {MIN_SIDE} x {MIN_SIDE} samples ({name} has {rows} rows x "
            f"{cols} columns)",
        )
    if max(rows, cols) > MAX_SIDE:
        raise SceneError(
            FIELD,
            f"a map of at most {MAX_SIDE} samples a side ({name} has {rows} rows x {cols} columns)",
        )


def _checked(heights: np.ndarray, name: str) -> np.ndarray:
    _check_kind(heights.dtype, name)
    _check_shape(heights.shape, name)
    heights = np.array(heights, dtype=np.float64)  # a copy: never a view of a reader's buffer
    infinite = np.isinf(heights)
    if infinite.any():
        row, col = (int(i) for i in np.argwhere(infinite)[0])
        count = int(infinite.sum())
        raise SceneError(
            FIELD,
            f"a height map without infinite values ({name} has {count} Inf "
            f"sample{'' if count == 1 else 's'}, the first at row {row}, column {col}; NaN marks "
            "an unmeasured sample)",
        )
    if np.isnan(heights).all():
        raise SceneError(
            FIELD, f"a height map with a measured sample ({name} holds only NaN: unmeasured)"
        )
    return heights


def _scaled(heights: np.ndarray, scale: float, name: str) -> np.ndarray:
    if not math.isfinite(scale):
        raise SceneError("surface.scale", "a finite number (mm per stored unit)", scale)
    with np.errstate(over="ignore"):
        heights = heights * scale
    if np.isinf(heights).any():
        raise SceneError(
            FIELD, f"a height map that stays finite in mm ({name} times scale {scale:g} overflows)"
        )
    return heights


def _npy(path: Path):
    fmt = np.lib.format
    with open(path, "rb") as f:  # the header first: refuse before loading anything
        version = fmt.read_magic(f)
        read_header = fmt.read_array_header_1_0 if version == (1, 0) else fmt.read_array_header_2_0
        shape, _, dtype = read_header(f)
    _check_kind(dtype, path.name)
    _check_shape(shape, path.name)
    return np.load(path, allow_pickle=False), None


def _x3p(path: Path):
    import x3pio

    x3p = x3pio.read(path)
    if not isinstance(x3p, x3pio.Surface):
        kind = type(x3p).__name__.lower()
        raise SceneError(FIELD, f"an x3p surface on a regular grid ({path.name} holds a {kind})")
    header = x3p.header
    if (
        header.x.axis_type is not x3pio.AxisType.INCREMENTAL
        or header.y.axis_type is not x3pio.AxisType.INCREMENTAL
    ):
        raise SceneError(
            FIELD,
            f"an x3p surface on a regular grid ({path.name} is a non-regular grid: its x or y "
            "axis is absolute)",
        )
    if not x3p.layers:
        raise SceneError(FIELD, f"an x3p surface with a layer of heights ({path.name} has none)")
    dx, dy = float(header.x.increment), float(header.y.increment)
    if not (dx > 0 and dy > 0):
        raise SceneError(
            FIELD,
            f"an x3p grid with positive spacings ({path.name} has x increment {dx:g} m, "
            f"y increment {dy:g} m)",
        )
    z = np.asarray(x3p.layers[0].z)  # (SizeY rows along our z, SizeX columns along our x), metres
    _check_shape(z.shape, path.name)
    return z * 1e3, (dx * 1e3, dy * 1e3)


def _tiff(path: Path):
    import tifffile

    with tifffile.TiffFile(path) as tif:  # the shape and type first: refuse before decoding
        series = tif.series[0]
        dtype = np.dtype(series.dtype)
        if not (dtype.kind == "u" or dtype in (np.float32, np.float64)):
            raise SceneError(
                FIELD,
                f"a TIFF of 32- or 64-bit floats or unsigned integers ({path.name} holds {dtype})",
            )
        _check_shape(tuple(series.shape), path.name)
        return tif.asarray(), None


def _png(path: Path):
    import cv2

    image = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if image is None:
        raise SceneError(FIELD, f"a readable PNG ({path.name} could not be decoded)")
    channels = 1 if image.ndim == 2 else image.shape[2]
    if image.dtype != np.uint16 or channels != 1:
        kind = "greyscale" if channels == 1 else f"with {channels} channels"
        raise SceneError(
            FIELD, f"a 16-bit greyscale PNG ({path.name} is {image.dtype.itemsize * 8}-bit {kind})"
        )
    return image, None
