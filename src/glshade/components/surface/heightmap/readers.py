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
  surface on a regular grid (incremental x and y axes) with increments in
  :data:`SPACING_RANGE_MM` is accepted; unmeasured points (NaN) are kept as NaN, like NaN
  in any other format.
- ``.tif``/``.tiff`` (``tifffile``): one page, a 2-D greyscale image of 32- or 64-bit
  floats or unsigned integers, uncompressed or deflate (zlib), times ``scale``. No spacing.
- ``.png`` (OpenCV): 16-bit greyscale only, times ``scale``. No spacing.

Every map needs at least :data:`MIN_SIDE` and at most :data:`MAX_SIDE` samples along each
side, no infinite values, and heights (after ``scale``) within :data:`HEIGHT_LIMIT_MM`.
NaN marks an unmeasured sample (the surface component masks or fills them: its ``fill``);
a map needs at least one measured sample. Every problem is a
:class:`~glshade.errors.SceneError` of one line for ``surface.file`` (or ``surface.scale``)
that names the file and what is wrong.

Hostile files
    Only a regular file is opened, and it is looked at before it is opened (a FIFO, a
    device or a socket is refused without opening it; the open itself never blocks, and
    what was opened is checked again). Every reader takes the map's size from the file's
    header (the .npy header, the x3p's ``main.xml`` and its zip directory, the TIFF's first
    page, the PNG's IHDR) and refuses, before decoding anything, a map whose loading would
    exceed the memory budget (:func:`check_map_size`). A header that lies about the data
    that follows (more, or less) is refused having decoded at most what it declares: the
    .npy's file size must be its header's, a zip member's sizes must be ones deflate can
    produce (and zipfile never inflates past the declared size), a TIFF's segments and a
    PNG's image data are inflated through a bounded stream first, counting bytes.

:func:`cached_height_map` keeps the last map, keyed by path, modification time, size and
scale, so an edited file is read again; the arrays it hands out are read-only because they
are shared.
"""

from __future__ import annotations

import functools
import math
import os
import stat
import struct
import tokenize
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import TYPE_CHECKING, BinaryIO, cast

import numpy as np

from glshade.components.surface.heightmap import HEIGHT_LIMIT_MM, SPACING_RANGE_MM
from glshade.errors import SceneError
from glshade.logs import silenced

if TYPE_CHECKING:  # the formats' libraries are loaded by the first map of each
    from io import BufferedIOBase
    from zipfile import ZipInfo

    from tifffile import TiffPage
    from x3pio import FileInfo

FIELD = "surface.file"
SUFFIXES = (".npy", ".x3p", ".tif", ".tiff", ".png")
#: The fewest samples along a side (the bicubic spline needs a 4 x 4 block).
MIN_SIDE = 4
#: The most samples along a side: the GL_MAX_TEXTURE_SIZE that OpenGL 4.5, which glshade
#: requires, guarantees (a driver may offer more, never less), so every map read fits
#: the renderer's texture.
MAX_SIDE = 16384
#: Peak memory per sample of a map read, turned into the render-ready grid and uploaded
#: as a texture (measured with ``/usr/bin/time -v glshade render`` on 2048² and 4096²
#: maps in every format, fill "none": 40-50 bytes; see docs/robustness.md): the float64
#: map (8), the NaN mask and the holes (2), the texture's three float32 channels (12),
#: the float64 heights the oracle reads (8), the texture's upload (a 12-byte copy and the
#: driver's own 12) and the decoder's buffers before them.
BYTES_PER_SAMPLE = 56
#: Memory per byte of an x3p's ``main.xml`` while it is parsed (measured: 7.2 for a map
#: stored as XML text, ``DataList``).
XML_BYTES_PER_BYTE = 8
#: The largest expansion deflate can give: 258 bytes from 2 bits.
DEFLATE_MAX_RATIO = 1032

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
#: How much of a compressed segment is read and inflated at a time (bytes).
_PIECE = 1 << 20

#: What a format's reader gives: the samples as stored and the spacing the file carries
#: (mm, along x and along z), if any.
_Read = tuple[np.ndarray, tuple[float, float] | None]


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
    reader = {".npy": _npy, ".x3p": _x3p, ".tif": _tiff, ".tiff": _tiff, ".png": _png}[suffix]
    with _open_regular(path) as stream:
        size = os.fstat(stream.fileno()).st_size
        try:
            heights, spacing = reader(stream, name, size)
        except SceneError:
            raise
        except _DAMAGED + _library_errors(suffix) as exc:
            detail = " ".join(str(exc).split())[:120] or "no detail"
            raise SceneError(
                FIELD, f"a readable height map ({name}: {type(exc).__name__}: {detail})"
            ) from None
    heights = _checked(heights, name)
    heights = _scaled(heights, 1.0 if suffix == ".x3p" else scale, name, suffix == ".x3p")
    heights.flags.writeable = False
    return HeightMap(heights, spacing, str(path))


@functools.lru_cache(maxsize=1)
def load_height_map(path_str: str, mtime_ns: int, size: int, scale: float) -> HeightMap:
    """:func:`read_height_map`, cached on the path and the file's modification time and size
    (which only serve as the key). One map is kept: the memory budget is one map's."""
    return read_height_map(path_str, scale)


def cached_height_map(path: str | os.PathLike[str], scale: float = 1.0) -> HeightMap:
    """:func:`read_height_map`, read again only when the file changed."""
    from glshade.files import note_input

    path_str = os.fspath(path)
    note_input(path_str)  # a file this run reads: never one of its outputs
    try:
        st = os.stat(path_str)
    except OSError:
        return read_height_map(path_str, scale)  # names the problem; nothing to cache
    if not stat.S_ISREG(st.st_mode):
        return read_height_map(path_str, scale)  # refused: nothing to cache
    return load_height_map(path_str, st.st_mtime_ns, st.st_size, float(scale))


def memory_budget_bytes() -> int:
    """The memory budget a map must fit (``GLSHADE_MEMORY_BUDGET_MB``, 2048 MiB unset)."""
    from glshade.budget import memory_budget_from_env  # the renderer's one definition

    return memory_budget_from_env()


def check_map_size(
    name: str, shape: tuple[int, ...], dtype: np.dtype, extra_bytes: int = 0
) -> None:
    """Refuse, before decoding it, a map whose declared ``shape`` (rows, columns) of
    ``dtype`` is not 2-D with sides in [:data:`MIN_SIDE`, :data:`MAX_SIDE`], or whose
    loading (:data:`BYTES_PER_SAMPLE` a sample, plus ``extra_bytes`` the decoder holds
    besides: a file read whole, an XML tree) exceeds :func:`memory_budget_bytes`."""
    _check_shape(shape, name)
    rows, cols = shape
    samples = rows * cols
    budget = memory_budget_bytes()
    need = samples * BYTES_PER_SAMPLE + extra_bytes
    if need > budget:
        room = max(0, budget - extra_bytes) // BYTES_PER_SAMPLE
        raise SceneError(
            FIELD,
            f"a map that loads within the memory budget (GLSHADE_MEMORY_BUDGET_MB = "
            f"{mib_text(budget)} MiB at {BYTES_PER_SAMPLE} bytes a sample: at most {room} samples; "
            f"{name} declares {rows} x {cols} = {samples} samples of {dtype}, "
            f"{mib_text(samples * dtype.itemsize)} MiB in the file, {mib_text(need)} MiB loaded)",
        )


def mib_text(size: int) -> str:
    """``size`` bytes in MiB, to 3 significant digits below 100 MiB."""
    mib = size / 2**20
    return f"{mib:.0f}" if mib >= 100 else f"{mib:.3g}"


def _open_regular(path: Path) -> BinaryIO:
    """``path`` opened for reading if it is a regular file (a symbolic link is followed),
    else a SceneError of one line. The type is looked up before opening (opening a device
    can act on it), and the open cannot block (O_NONBLOCK: a FIFO swapped in meanwhile
    opens at once, and is then refused by the check of what was opened)."""
    name = path.name
    try:
        _refuse_special(os.stat(path).st_mode, name)
        descriptor = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        raise SceneError(FIELD, "an existing height map file", str(path)) from None
    except PermissionError:
        raise SceneError(FIELD, f"a readable file ({name}: permission denied)") from None
    except OSError as exc:
        raise SceneError(FIELD, f"a readable file ({name}: {exc.strerror})") from None
    try:
        _refuse_special(os.fstat(descriptor).st_mode, name)
    except SceneError:
        os.close(descriptor)
        raise
    stream = os.fdopen(descriptor, "rb")
    # named by its path, not its descriptor: tifffile splits the name as a path
    stream.raw.name = str(path)  # type: ignore[attr-defined]
    return stream


def _refuse_special(mode: int, name: str) -> None:
    from glshade.files import special_kind

    kind = special_kind(mode)
    if kind is not None:
        raise SceneError(
            FIELD, f"a regular file ({name} is {kind}; glshade reads only regular files)"
        )


def _library_errors(suffix: str) -> tuple[type[BaseException], ...]:
    if suffix == ".x3p":
        import zipfile

        import x3pio

        return (x3pio.X3pError, zipfile.BadZipFile)
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
    """``heights`` (a reader's fresh array) as a float64 array of its own, refused with
    infinite samples or none measured; no temporary of the map's size."""
    heights = np.asarray(heights)
    _check_kind(heights.dtype, name)
    _check_shape(heights.shape, name)
    if not (
        heights.dtype == np.float64
        and heights.dtype.isnative
        and heights.flags.writeable
        and heights.flags.c_contiguous
    ):  # a copy, unless the reader's array already is one (never a read-only buffer's view)
        heights = np.array(heights, dtype=np.float64)
    lowest, highest = _extremes(heights)
    if math.isinf(lowest) or math.isinf(highest):
        infinite = np.isinf(heights)
        row, col = (int(i) for i in np.argwhere(infinite)[0])
        count = int(infinite.sum())
        raise SceneError(
            FIELD,
            f"a height map without infinite values ({name} has {count} Inf "
            f"sample{'' if count == 1 else 's'}, the first at row {row}, column {col}; NaN marks "
            "an unmeasured sample)",
        )
    if math.isnan(highest):
        raise SceneError(
            FIELD, f"a height map with a measured sample ({name} holds only NaN: unmeasured)"
        )
    return heights


def _extremes(heights: np.ndarray) -> tuple[float, float]:
    """The lowest and highest sample, NaN ignored (NaN when all are), without warnings."""
    return float(np.fmin.reduce(heights, axis=None)), float(np.fmax.reduce(heights, axis=None))


def _scaled(heights: np.ndarray, scale: float, name: str, has_units: bool) -> np.ndarray:
    """``heights`` times ``scale`` in place, refused beyond :data:`HEIGHT_LIMIT_MM` (checked
    first, so nothing overflows)."""
    if not math.isfinite(scale) or scale == 0:
        raise SceneError("surface.scale", "a finite non-zero number (mm per stored unit)", scale)
    lowest, highest = _extremes(heights)
    reach = max(abs(lowest), abs(highest)) * abs(scale)  # a Python float: inf, never a warning
    if reach > HEIGHT_LIMIT_MM:
        span = f"{name} holds heights from {lowest:g} to {highest:g}"
        if has_units:
            raise SceneError(
                FIELD,
                f"a map with heights within ±{HEIGHT_LIMIT_MM:g} mm ({span} mm)",
            )
        raise SceneError(
            "surface.scale",
            f"a scale that keeps the heights within ±{HEIGHT_LIMIT_MM:g} mm ({span} stored "
            f"units; times {scale:g} they reach {reach:.6g} mm)",
        )
    if scale != 1.0:
        heights *= scale
    return heights


# ------------------------------------------------------------------ .npy
def _npy(stream: BinaryIO, name: str, size: int) -> _Read:
    fmt = np.lib.format
    version = fmt.read_magic(stream)  # the header first: refuse before loading anything
    read_header = fmt.read_array_header_1_0 if version == (1, 0) else fmt.read_array_header_2_0
    shape, _, dtype = read_header(stream)
    _check_kind(dtype, name)
    check_map_size(name, shape, dtype)
    start = stream.tell()
    declared = math.prod(shape) * dtype.itemsize
    if size - start != declared:
        raise SceneError(
            FIELD,
            f"a .npy whose samples fill the file ({name}'s header declares {declared} bytes "
            f"of samples, the file holds {size - start})",
        )
    stream.seek(0)
    return np.lib.format.read_array(stream, allow_pickle=False), None


# ------------------------------------------------------------------ .x3p
def _x3p(stream: BinaryIO, name: str, size: int) -> _Read:
    import zipfile

    import x3pio

    with zipfile.ZipFile(stream) as archive:  # its directory only: nothing is inflated
        members = archive.infolist()
    for member in members:
        _check_zip_member(member, name)
    xml = max((m.file_size for m in members if m.filename.split("/")[-1] == "main.xml"), default=0)
    budget = memory_budget_bytes()
    if xml * XML_BYTES_PER_BYTE > budget:
        raise SceneError(
            FIELD,
            f"an x3p whose main.xml parses within the memory budget (GLSHADE_MEMORY_BUDGET_MB "
            f"= {mib_text(budget)} MiB at {XML_BYTES_PER_BYTE} bytes a byte of XML: at most "
            f"{mib_text(budget // XML_BYTES_PER_BYTE)} MiB; {name} declares a main.xml of "
            f"{mib_text(xml)} MiB)",
        )
    stream.seek(0)
    description = x3pio.info(stream)  # main.xml only: the declared sizes and types
    _check_x3p_description(description, name, x3pio)
    rows, cols = description.shape
    dtype = np.dtype(description.header.z.data_type.name.lower())
    other_layers = (description.layer_count - 1) * rows * cols * (dtype.itemsize + 8)
    check_map_size(
        name, (rows, cols), dtype, size + xml * XML_BYTES_PER_BYTE + max(0, other_layers)
    )
    stream.seek(0)
    x3p = x3pio.read(stream)
    if not x3p.layers:
        raise SceneError(FIELD, f"an x3p surface with a layer of heights ({name} has none)")
    z = np.asarray(x3p.layers[0].z)  # (SizeY rows along our z, SizeX columns along our x), metres
    _check_shape(z.shape, name)
    header = x3p.header
    spacing = (float(header.x.increment) * 1e3, float(header.y.increment) * 1e3)
    return np.multiply(z, 1e3, dtype=np.float64), spacing


def _check_zip_member(member: ZipInfo, name: str) -> None:
    """A member's declared sizes must be ones its compression can give: stored, the same;
    deflated, at most :data:`DEFLATE_MAX_RATIO` times the compressed size and no more
    compressed bytes than a deflate stream of that size needs."""
    import zipfile

    compressed, declared = member.compress_size, member.file_size
    if member.compress_type == zipfile.ZIP_STORED:
        lies = compressed != declared
    elif member.compress_type == zipfile.ZIP_DEFLATED:
        lies = (
            declared > DEFLATE_MAX_RATIO * compressed + 1024
            or compressed > declared + declared // 256 + 1024
        )
    else:
        raise SceneError(
            FIELD,
            f"an x3p whose members are stored or deflated ({name}'s {member.filename} uses zip "
            f"compression method {member.compress_type})",
        )
    if lies:
        raise SceneError(
            FIELD,
            f"an x3p whose zip directory tells the truth ({name}'s {member.filename} declares "
            f"{declared} bytes from {compressed} compressed bytes, which its compression "
            "cannot give)",
        )


def _check_x3p_description(description: FileInfo, name: str, x3pio: ModuleType) -> None:
    if description.feature_type is not x3pio.FeatureType.SURFACE:
        kind = description.feature_type.name.lower().replace("_", "")
        raise SceneError(FIELD, f"an x3p surface on a regular grid ({name} holds a {kind})")
    header = description.header
    if (
        header.x.axis_type is not x3pio.AxisType.INCREMENTAL
        or header.y.axis_type is not x3pio.AxisType.INCREMENTAL
    ):
        raise SceneError(
            FIELD,
            f"an x3p surface on a regular grid ({name} is a non-regular grid: its x or y "
            "axis is absolute)",
        )
    if description.layer_count < 1:
        raise SceneError(FIELD, f"an x3p surface with a layer of heights ({name} has none)")
    dx, dy = float(header.x.increment), float(header.y.increment)
    low, high = SPACING_RANGE_MM
    if not (low <= dx * 1e3 <= high and low <= dy * 1e3 <= high):
        raise SceneError(
            FIELD,
            f"an x3p grid with increments in [{low / 1e3:g}, {high / 1e3:g}] m ({name} has x "
            f"increment {dx:g} m, y increment {dy:g} m)",
        )


# ------------------------------------------------------------------ .tif
#: TIFF compressions read (uncompressed; deflate as Adobe and as the TIFF spec number it).
_TIFF_DEFLATE = (8, 32946)


def _tiff(stream: BinaryIO, name: str, size: int) -> _Read:
    import tifffile

    with silenced("tifffile"), tifffile.TiffFile(stream) as tif:  # the first page's tags first
        pages = len(tif.pages)
        if pages != 1:
            raise SceneError(FIELD, f"a TIFF of one page ({name} has {pages or 'none'})")
        page = tif.pages.first
        dtype = None if page.dtype is None else np.dtype(page.dtype)
        if dtype is None or not (dtype.kind == "u" or dtype in (np.float32, np.float64)):
            raise SceneError(
                FIELD,
                f"a TIFF of 32- or 64-bit floats or unsigned integers ({name} holds "
                f"{dtype if dtype is not None else 'samples numpy cannot hold'})",
            )
        separate, depth, _, _, samples = page.shaped
        if separate * depth * samples != 1:
            _check_shape(tuple(page.shape), name)  # names the extra axis
            raise SceneError(FIELD, f"a 2-D greyscale TIFF ({name} has shape {page.shaped})")
        check_map_size(name, (page.imagelength, page.imagewidth), dtype)
        if page.bitspersample != dtype.itemsize * 8:
            raise SceneError(
                FIELD, f"a TIFF of whole-byte samples ({name} has {page.bitspersample} bits)"
            )
        _check_tiff_segments(page, stream, name, size, dtype.itemsize)
        return page.asarray(maxworkers=1), None


def _tiff_segment_sizes(page: TiffPage, itemsize: int) -> list[tuple[int, int]]:
    """Each segment's (least, most) decoded bytes: a tile is always whole; a strip holds
    its rows, the last one its rows or a whole strip's."""
    width, length = page.imagewidth, page.imagelength
    if page.is_tiled:
        tile = page.tilewidth * page.tilelength * page.tiledepth * itemsize
        count = -(-width // page.tilewidth) * -(-length // page.tilelength)
        return [(tile, tile)] * count
    rows = min(page.rowsperstrip, length) or length
    full = rows * width * itemsize
    sizes = [(full, full)] * (-(-length // rows))
    sizes[-1] = ((length - rows * (len(sizes) - 1)) * width * itemsize, full)
    return sizes


def _check_tiff_segments(
    page: TiffPage, stream: BinaryIO, name: str, size: int, itemsize: int
) -> None:
    """Every strip or tile lies in the file and decodes to the bytes its place in the
    image takes (deflate: inflated through a bounded stream and counted, never kept)."""
    compression = int(page.compression)
    if compression != 1 and compression not in _TIFF_DEFLATE:
        raise SceneError(
            FIELD,
            f"an uncompressed or deflate (zlib) TIFF ({name} is compressed with "
            f"{_tiff_compression_name(compression)})",
        )
    if page.is_tiled and (page.tilewidth % 16 or page.tilelength % 16):
        raise SceneError(
            FIELD,
            f"a TIFF whose tiles are multiples of 16 samples a side ({name}'s are "
            f"{page.tilewidth} x {page.tilelength})",
        )
    sizes = _tiff_segment_sizes(page, itemsize)
    offsets, counts = page.dataoffsets, page.databytecounts
    image = page.imagewidth * page.imagelength * itemsize
    if len(offsets) != len(sizes) or len(counts) != len(sizes):
        raise SceneError(
            FIELD,
            f"a TIFF whose strips or tiles cover its image ({name} lists {len(offsets)} for "
            f"the {len(sizes)} its image needs)",
        )
    if sizes[0][1] > image + _PIECE:
        raise SceneError(
            FIELD,
            f"a TIFF whose strips or tiles are no larger than its image ({name}'s hold "
            f"{sizes[0][1]} bytes, the image {image})",
        )
    segments = zip(offsets, counts, sizes, strict=True)
    for index, (offset, count, (least, most)) in enumerate(segments):
        if count <= 0 or offset < 0 or offset + count > size:
            raise SceneError(
                FIELD,
                f"a TIFF whose strips and tiles lie in the file ({name}'s segment {index} "
                f"takes bytes {offset} to {offset + count}, the file has {size})",
            )
        got = count if compression == 1 else _inflated_size(stream, offset, count, most)
        if not least <= got <= most:
            raise SceneError(
                FIELD,
                f"a TIFF whose data matches its tags ({name}'s segment {index} holds "
                f"{'more than ' if got > most else ''}{min(got, most + 1)} bytes of samples, "
                f"its tags declare {most})",
            )


def _tiff_compression_name(compression: int) -> str:
    import tifffile

    try:
        return tifffile.COMPRESSION(compression).name
    except ValueError:
        return f"compression {compression}"


def _inflated_size(stream: BinaryIO, offset: int, count: int, most: int) -> int:
    """The bytes the zlib stream at ``offset`` (``count`` bytes) inflates to, inflating at
    most ``most + 1`` of them, :data:`_PIECE` at a time; data after the stream's end is
    ignored, as ``zlib.decompress`` ignores it."""
    inflater = zlib.decompressobj()
    produced = 0
    stream.seek(offset)
    left = count
    while left and not inflater.eof and produced <= most:
        pending = stream.read(min(left, _PIECE))
        if not pending:
            break
        left -= len(pending)
        while pending and not inflater.eof and produced <= most:
            produced += len(inflater.decompress(pending, min(_PIECE, most + 1 - produced)))
            pending = inflater.unconsumed_tail
    if produced <= most and not inflater.eof:
        raise zlib.error("the compressed data ends before its stream does")
    return produced


# ------------------------------------------------------------------ .png
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_PNG_CHANNELS = {0: 1, 2: 3, 3: 1, 4: 2, 6: 4}
#: Adam7's passes: (first column, first row, column step, row step).
_ADAM7 = (
    (0, 0, 8, 8),
    (4, 0, 8, 8),
    (0, 4, 4, 8),
    (2, 0, 4, 4),
    (0, 2, 2, 4),
    (1, 0, 2, 2),
    (0, 1, 1, 2),
)


def _png(stream: BinaryIO, name: str, size: int) -> _Read:
    """The IHDR first (refuse before decoding); then the image data checked through a
    bounded stream, and OpenCV handed a PNG of IHDR, IDAT and IEND only, every CRC and
    filter byte checked: libpng has nothing left to warn about on stderr."""
    import cv2

    head = stream.read(33)
    if len(head) < 33 or head[:8] != _PNG_SIGNATURE or head[8:16] != b"\x00\x00\x00\rIHDR":
        raise SceneError(FIELD, f"a readable PNG ({name} has no PNG signature and header)")
    width, height, bits, colour, *methods, interlace = struct.unpack(">IIBBBBB", head[16:29])
    if bits != 16 or colour != 0:
        raise SceneError(FIELD, f"a 16-bit greyscale PNG ({name} is {_png_kind(bits, colour)})")
    check_map_size(name, (height, width), np.dtype(np.uint16), extra_bytes=size)
    if zlib.crc32(head[12:29]) != struct.unpack(">I", head[29:33])[0] or methods != [0, 0]:
        raise SceneError(FIELD, f"a readable PNG ({name}'s header is damaged)")
    if interlace not in (0, 1):
        raise SceneError(FIELD, f"a readable PNG ({name} has interlace method {interlace})")
    chunks = _png_image_chunks(stream, name, _png_rows(width, height, interlace))
    image = cv2.imdecode(_minimal_png(stream, head, chunks), cv2.IMREAD_UNCHANGED)
    if image is None or image.shape != (height, width) or image.dtype != np.uint16:
        raise SceneError(FIELD, f"a readable PNG ({name} could not be decoded)")
    return image, None


def _png_kind(bits: int, colour: int) -> str:
    if colour == 0:
        return f"{bits}-bit greyscale"
    if colour == 3:
        return f"{bits}-bit with a palette"
    if colour in _PNG_CHANNELS:
        return f"{bits}-bit with {_PNG_CHANNELS[colour]} channels"
    return f"{bits}-bit of colour type {colour}"


def _png_rows(width: int, height: int, interlace: int) -> list[tuple[int, int, int]]:
    """The filtered rows of a 16-bit greyscale image as (offset of the first, bytes a row
    with its filter byte, rows), one entry per Adam7 pass when interlaced."""
    passes = _ADAM7 if interlace else ((0, 0, 1, 1),)
    rows, offset = [], 0
    for column, row, column_step, row_step in passes:
        columns = max(0, -(-(width - column) // column_step))
        count = max(0, -(-(height - row) // row_step)) if columns else 0
        rows.append((offset, 1 + 2 * columns, count))
        offset += (1 + 2 * columns) * count
    return rows


def _png_image_chunks(
    stream: BinaryIO, name: str, rows: Sequence[tuple[int, int, int]]
) -> list[tuple[int, int]]:
    """(offset, length) of every IDAT chunk's data, checked: each CRC, and the data
    inflated through a bounded stream (at most the declared bytes and one more,
    :data:`_PIECE` at a time, never kept) to exactly the declared rows with valid filter
    bytes. Ancillary chunks are skipped unread; an unknown critical chunk is refused."""
    expected = rows[-1][0] + rows[-1][1] * rows[-1][2]
    inflater = zlib.decompressobj()
    produced, chunks = 0, []
    stream.seek(33)
    while produced <= expected:
        header = stream.read(8)
        if len(header) < 8:
            break
        length, kind = struct.unpack(">I4s", header)
        if kind == b"IEND" or length >= 1 << 31:
            break
        if kind != b"IDAT":
            if kind[:1].isupper() and kind != b"PLTE":
                raise SceneError(FIELD, f"a readable PNG ({name} has a critical chunk {kind!r})")
            stream.seek(length + 4, os.SEEK_CUR)
            continue
        chunks.append((stream.tell(), length))
        produced = _inflate_png_chunk(stream, name, length, inflater, produced, expected, rows)
    if produced != expected or not inflater.eof:
        more = "more than " if produced > expected else ""
        raise SceneError(
            FIELD,
            f"a PNG whose image data matches its header ({name}'s data inflates to {more}"
            f"{min(produced, expected + 1)} bytes, its header declares {expected})",
        )
    return chunks


def _inflate_png_chunk(
    stream: BinaryIO,
    name: str,
    length: int,
    inflater: zlib._Decompress,
    produced: int,
    expected: int,
    rows: Sequence[tuple[int, int, int]],
) -> int:
    """Inflate one IDAT chunk's data on from ``produced`` bytes, checking its CRC and the
    filter bytes of the rows it holds; the bytes produced so far."""
    crc = zlib.crc32(b"IDAT")
    left = length
    while left and produced <= expected:
        pending = stream.read(min(left, _PIECE))
        if not pending:
            break
        left -= len(pending)
        crc = zlib.crc32(pending, crc)
        while pending and not inflater.eof and produced <= expected:
            out = inflater.decompress(pending, min(_PIECE, expected + 1 - produced))
            if not _filters_valid(out, produced, rows):
                raise SceneError(
                    FIELD, f"a readable PNG ({name} has a row whose filter type is not 0 to 4)"
                )
            produced += len(out)
            pending = inflater.unconsumed_tail
    stored = stream.read(4)
    if left == 0 and (len(stored) < 4 or struct.unpack(">I", stored)[0] != crc):
        raise SceneError(FIELD, f"a readable PNG ({name}'s image data fails its CRC)")
    return produced


def _filters_valid(piece: bytes, start: int, rows: Sequence[tuple[int, int, int]]) -> bool:
    """Whether every row that starts within ``piece`` (bytes ``start`` on of the inflated
    data) starts with a filter type of 0 to 4."""
    data = np.frombuffer(piece, np.uint8)
    stop = start + len(data)
    for first, length, count in rows:
        low, high = max(start, first), min(stop, first + length * count)
        begin = low + (first - low) % length
        if begin < high and int(data[begin - start : high - start : length].max()) > 4:
            return False
    return True


def _minimal_png(stream: BinaryIO, head: bytes, chunks: list[tuple[int, int]]) -> np.ndarray:
    """A PNG of the signature, the IHDR, the IDAT chunks in ``chunks`` (read again into
    one buffer, CRCs as checked) and IEND, as OpenCV's decoder takes it."""
    total = len(head) + sum(12 + length for _, length in chunks) + 12
    buffer = bytearray(total)
    buffer[: len(head)] = head
    at = len(head)
    for offset, length in chunks:
        stream.seek(offset - 8)
        # the file _open_regular opened: a buffered reader, which reads into a buffer
        cast("BufferedIOBase", stream).readinto(memoryview(buffer)[at : at + 12 + length])
        at += 12 + length
    buffer[at:] = struct.pack(">I4sI", 0, b"IEND", zlib.crc32(b"IEND"))
    return np.frombuffer(buffer, np.uint8)
