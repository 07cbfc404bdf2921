"""Hostile height maps through the real CLI: ``glshade render SCENE --size 16 -o out.png``
on each must print one line, exit 2 and write nothing.

The table holds damaged and malformed files of every format, maps whose declared size is
16384² (built cheaply: a sparse .npy is a header and a seek, a big zip member a short
deflate stream repeated, a big TIFF or PNG a forged header), headers that lie about the
data after them (zip bombs, TIFF strips and PNG data that inflate beyond or short of what
is declared), special files named as the map, and spacings, origins and scales outside
their ranges. Accepted maps at the edges of those ranges render with nothing on stderr
(no NumPy warning).
"""

from __future__ import annotations

import io
import os
import socket
import struct
import subprocess
import zlib
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import pytest
import tifffile
import x3pio

from glshade_process import run_glshade

SIDE = 16384  # the declared side of the big maps
MIB = 1 << 20


# ------------------------------------------------------------------ builders
def _npy_header(path: Path, shape: tuple[int, ...], descr: str = "<f8") -> int:
    """Write a .npy header for ``shape``; the offset its data starts at."""
    with open(path, "wb") as f:
        header = {"descr": descr, "fortran_order": False, "shape": shape}
        np.lib.format.write_array_header_1_0(f, header)
        return f.tell()


def _sparse_npy(path: Path, shape: tuple[int, int], descr: str = "<f8") -> None:
    """A .npy of ``shape`` whose data is a hole: a header and a seek."""
    start = _npy_header(path, shape, descr)
    with open(path, "r+b") as f:
        f.truncate(start + shape[0] * shape[1] * np.dtype(descr).itemsize)


def _npy_with_data(path: Path, shape: tuple[int, int], data_bytes: int) -> None:
    """A header for ``shape`` followed by ``data_bytes`` bytes (a header that lies)."""
    start = _npy_header(path, shape)
    with open(path, "r+b") as f:
        f.truncate(start + data_bytes)


def _deflated(repeated: bytes, times: int, head: bytes = b"", zlib_format: bool = False):
    """A deflate stream of ``head`` then ``repeated`` ``times`` times, built from one
    compressed copy (after a full flush the compressor's output for the same input is
    the same), and the size it inflates to. The checksum of a zlib stream is left
    wrong: nothing reads that far."""
    compressor = zlib.compressobj(9, zlib.DEFLATED, zlib.MAX_WBITS if zlib_format else -15)
    first = compressor.compress(head) + compressor.flush(zlib.Z_FULL_FLUSH)
    chunk = compressor.compress(repeated) + compressor.flush(zlib.Z_FULL_FLUSH)
    return first + chunk * times + compressor.flush(), len(head) + len(repeated) * times


def _zip(path: Path, members: list[tuple[str, bytes, int, int]]) -> None:
    """A zip of raw deflate ``members`` (name, compressed bytes, declared size, CRC),
    written by hand so the declared size can be anything."""
    out, directory = io.BytesIO(), io.BytesIO()
    for name, compressed, declared, crc in members:
        offset = out.tell()
        fields = (20, 0, 8, 0, 0x21, crc, len(compressed), declared, len(name), 0)
        out.write(b"PK\x03\x04" + struct.pack("<5H3L2H", *fields) + name.encode())
        out.write(compressed)
        central = (20, 20, 0, 8, 0, 0x21, crc, len(compressed), declared, len(name), 0, 0, 0, 0)
        directory.write(b"PK\x01\x02" + struct.pack("<6H3L5H", *central))
        directory.write(struct.pack("<2L", 0, offset) + name.encode())
    start = out.tell()
    out.write(directory.getvalue())
    end = (0, 0, len(members), len(members), len(directory.getvalue()), start, 0)
    out.write(b"PK\x05\x06" + struct.pack("<4H2LH", *end))
    path.write_bytes(out.getvalue())


def _main_xml(rows: int, cols: int, increment: str = "1e-05") -> str:
    """x3pio's main.xml for a float64 map of ``rows`` x ``cols``, its spacing ``increment``."""
    buffer = io.BytesIO()
    x3pio.write(buffer, np.zeros((5, 6)), x_scale=1e-5, y_scale=1e-5)
    xml = zipfile_read(buffer.getvalue(), "main.xml").decode()
    xml = xml.replace("<SizeX>6</SizeX>", f"<SizeX>{cols}</SizeX>")
    xml = xml.replace("<SizeY>5</SizeY>", f"<SizeY>{rows}</SizeY>")
    return xml.replace("<Increment>1e-05</Increment>", f"<Increment>{increment}</Increment>", 2)


def _x3p_text(path: Path, xml: str, data: tuple[bytes, int] | None) -> None:
    _x3p(path, xml.encode(), data)


def zipfile_read(data: bytes, name: str) -> bytes:
    import zipfile

    return zipfile.ZipFile(io.BytesIO(data)).read(name)


def _raw(data: bytes) -> bytes:
    compressor = zlib.compressobj(9, zlib.DEFLATED, -15)
    return compressor.compress(data) + compressor.flush()


def _x3p(path: Path, xml: bytes, data: tuple[bytes, int] | None) -> None:
    """An x3p of ``xml`` and a data member (compressed, declared size; its CRC left 0:
    these are refused before it is read), no checksum file."""
    members = [("main.xml", _raw(xml), len(xml), zlib.crc32(xml))]
    if data is not None:
        members.append(("bindata/data.bin", *data, 0))
    _zip(path, members)


def _big_x3p(path: Path) -> None:
    """main.xml declares 16384² float64; data.bin is 2 GiB of zeros in 2 MB of deflate."""
    data = _deflated(bytes(MIB), SIDE * SIDE * 8 // MIB)
    _x3p_text(path, _main_xml(SIDE, SIDE), data)


def _x3p_bomb(path: Path) -> None:
    """data.bin declares the 32 KiB of a 64 x 64 map; its stream inflates to 256 MiB."""
    _x3p_text(path, _main_xml(64, 64), (_deflated(bytes(MIB), 256)[0], 64 * 64 * 8))


def _x3p_overstated(path: Path) -> None:
    """data.bin declares 2 GiB from 100 compressed bytes: more than deflate can give."""
    _x3p_text(path, _main_xml(64, 64), (bytes(100), 1 << 31))


def _x3p_huge_xml(path: Path) -> None:
    """A main.xml of 1 GiB (a real map's XML then spaces), 1 MB compressed."""
    compressed, size = _deflated(b" " * MIB, 1024, head=_main_xml(64, 64).encode())
    _zip(path, [("main.xml", compressed, size, 0)])


def _x3p_without_data(path: Path) -> None:
    _x3p_text(path, _main_xml(64, 64), None)


def _x3p_broken_xml(path: Path) -> None:
    xml = _main_xml(64, 64)[:-40]
    _x3p_text(path, xml, (_raw(bytes(64 * 64 * 8)), 64 * 64 * 8))


def _x3p_increment(increment: str) -> Callable[[Path], None]:
    def build(path: Path) -> None:
        _x3p_text(path, _main_xml(8, 8, increment), (_raw(bytes(8 * 8 * 8)), 8 * 8 * 8))

    return build


def _tiff(
    path: Path,
    width: int,
    length: int,
    segment: bytes,
    *,
    compression: int = 8,
    tile: tuple[int, int] | None = (256, 256),
) -> None:
    """A forged little-endian float32 TIFF: every strip or tile holds ``segment`` (one
    strip when not tiled)."""
    tags = [(256, 4, 1, width), (257, 4, 1, length), (258, 3, 1, 32), (259, 3, 1, compression)]
    tags += [(262, 3, 1, 1), (277, 3, 1, 1), (339, 3, 1, 3)]
    if tile is not None:
        count = -(-width // tile[0]) * -(-length // tile[1])
        tags += [(322, 4, 1, tile[0]), (323, 4, 1, tile[1])]
        offsets_tag, counts_tag = 324, 325
    else:
        count = 1
        tags += [(278, 4, 1, length)]
        offsets_tag, counts_tag = 273, 279
    entries = len(tags) + 2
    data_at = 8 + 2 + 12 * entries + 4
    arrays_at = data_at + len(segment)
    if count == 1:  # one offset and one count: in the tags themselves
        tags += [(offsets_tag, 4, 1, data_at), (counts_tag, 4, 1, len(segment))]
        arrays = b""
    else:
        tags += [(offsets_tag, 4, count, arrays_at), (counts_tag, 4, count, arrays_at + 4 * count)]
        arrays = struct.pack(f"<{count}L", *([data_at] * count))
        arrays += struct.pack(f"<{count}L", *([len(segment)] * count))
    ifd = struct.pack("<H", entries)
    for tag in sorted(tags):
        ifd += struct.pack("<HHLL", *tag)
    path.write_bytes(b"II*\x00" + struct.pack("<L", 8) + ifd + bytes(4) + segment + arrays)


def _big_tiff(path: Path) -> None:
    """16384² float32 in 4096 zlib tiles of 256², all pointing at one tiny stream."""
    _tiff(path, SIDE, SIDE, zlib.compress(bytes(256 * 256 * 4)))


def _tiff_bomb(path: Path) -> None:
    """64 x 64 float32 in one deflate strip (16 KiB declared) that inflates to 256 MiB."""
    _tiff(path, 64, 64, _deflated(bytes(MIB), 256, zlib_format=True)[0], tile=None)


def _tiff_short(path: Path) -> None:
    """64 x 64 float32 in one deflate strip that inflates to 1000 bytes only."""
    _tiff(path, 64, 64, zlib.compress(bytes(1000)), tile=None)


def _tiff_huge_tile(path: Path) -> None:
    """A 16 x 16 image in one tile of 65536²."""
    _tiff(path, 16, 16, zlib.compress(bytes(64)), tile=(65536, 65536))


def _tiff_truncated(path: Path) -> None:
    tifffile.imwrite(path, np.zeros((64, 64), np.float32))
    path.write_bytes(path.read_bytes()[:8000])


def _multipage_tiff(path: Path) -> None:
    with tifffile.TiffWriter(path) as tif:
        for _ in range(3):
            tif.write(np.zeros((8, 8), np.float32))


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def _png(path: Path, width: int, height: int, idat: bytes, bits: int = 16, colour: int = 0):
    """A PNG of one IHDR (``bits``, ``colour`` type), one IDAT chunk and IEND."""
    header = struct.pack(">IIBBBBB", width, height, bits, colour, 0, 0, 0)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n"
        + _png_chunk(b"IHDR", header)
        + _png_chunk(b"IDAT", idat)
        + _png_chunk(b"IEND", b"")
    )


def _png_truncated(path: Path) -> None:
    noise = np.random.default_rng(4).integers(0, 65535, (64, 64), dtype=np.uint16)
    cv2.imwrite(str(path), noise)
    path.write_bytes(path.read_bytes()[:4000])


def _save(array) -> Callable[[Path], None]:
    return lambda path: np.save(path, array)


def _only_nan_but_one(path: Path) -> None:
    heights = np.full((256, 256), np.nan)
    heights[0, 0] = 0.0
    np.save(path, heights)


def _socket(path: Path) -> None:
    with socket.socket(socket.AF_UNIX) as server:
        server.bind(str(path))


def _unreadable(path: Path) -> None:
    np.save(path, np.zeros((8, 8)))
    path.chmod(0)


GOOD = _save(np.outer(np.arange(8.0), np.ones(8)))  # 0 to 7 mm


# ------------------------------------------------------------------ the table
@dataclass(frozen=True)
class Case:
    """One hostile map: its file's name, how to make it (None: absent), a fragment the
    error line must contain, extra ``[surface]`` lines (replacing the default spacing when
    they set one) and environment."""

    file: str
    build: Callable[[Path], None] | None
    fragment: str
    surface: str = ""
    env: dict[str, str] = field(default_factory=dict)
    id: str = ""

    @property
    def name(self) -> str:
        return self.id or self.file


CASES = [
    # .npy
    Case("truncated.npy", lambda p: _npy_with_data(p, (64, 64), 1000), "the file holds 1000"),
    Case("longer.npy", lambda p: _npy_with_data(p, (8, 8), 9000), "declares 512 bytes"),
    Case("magic.npy", lambda p: p.write_bytes(b"\x93NUMPX" + bytes(100)), "a readable height"),
    Case("empty.npy", lambda p: p.write_bytes(b""), "a readable height map (empty.npy"),
    Case("nan.npy", _save(np.full((8, 8), np.nan)), "holds only NaN"),
    Case("inf.npy", _save(np.full((8, 8), -np.inf)), "64 Inf samples"),
    Case("row.npy", _save(np.zeros((1, 50))), "at least 4 x 4 samples (row.npy has 1 rows"),
    Case("column.npy", _save(np.zeros((50, 1))), "at least 4 x 4 samples"),
    Case("nothing.npy", _save(np.zeros((0, 0))), "at least 4 x 4 samples"),
    Case("flat.npy", _save(np.zeros(0)), "a 2-D map, rows x columns (flat.npy has shape (0,))"),
    Case(
        "pickled.npy",
        lambda p: np.save(p, np.array([[{}] * 4] * 4, dtype=object), allow_pickle=True),
        "(pickled.npy holds object)",
    ),
    Case("complex.npy", _save(np.zeros((8, 8), complex)), "(complex.npy holds complex128)"),
    Case("cube.npy", _save(np.zeros((4, 4, 4))), "(cube.npy has shape (4, 4, 4))"),
    Case("bool.npy", _save(np.zeros((8, 8), bool)), "(bool.npy holds bool)"),
    Case("struct.npy", _save(np.zeros((8, 8), "f8,f8")), "real integers or floats"),
    Case(
        "big.npy",
        lambda p: _sparse_npy(p, (SIDE, SIDE)),
        "(GLSHADE_MEMORY_BUDGET_MB = 2048 MiB at 56 bytes a sample: at most 38347922 samples; "
        "big.npy declares 16384 x 16384 = 268435456 samples of float64, 2048 MiB in the file, "
        "14336 MiB loaded)",
    ),
    Case("wide.npy", lambda p: _sparse_npy(p, (4, SIDE + 1)), "at most 16384 samples a side"),
    Case(
        "budget.npy",
        lambda p: _sparse_npy(p, (256, 256), "<u2"),
        "memory budget (GLSHADE_MEMORY_BUDGET_MB = 1 MiB at 56 bytes a sample: at most 18724 "
        "samples; budget.npy declares 256 x 256 = 65536 samples of uint16, 0.125 MiB in the "
        "file, 3.5 MiB loaded)",
        env={"GLSHADE_MEMORY_BUDGET_MB": "1"},
    ),
    Case(
        "harmonic.npy",
        _only_nan_but_one,
        'surface.fill: must be "nearest" for this map',
        env={"GLSHADE_MEMORY_BUDGET_MB": "40"},
    ),
    # .x3p
    Case("notzip.x3p", lambda p: p.write_bytes(b"PK\x03\x04 not a zip"), "a readable height"),
    Case(
        "nomain.x3p",
        lambda p: _zip(p, [("other.xml", _raw(b"<a/>"), 4, zlib.crc32(b"<a/>"))]),
        "no main.xml",
    ),
    Case("nodata.x3p", _x3p_without_data, "is missing from the container"),
    Case("brokenxml.x3p", _x3p_broken_xml, "main.xml is not valid XML"),
    Case(
        "profile.x3p",
        lambda p: x3pio.write(p, np.zeros(10), x_scale=1e-5),
        "(profile.x3p holds a profile)",
    ),
    Case("zero.x3p", _x3p_increment("0"), "Increment must not be zero"),
    Case("tiny.x3p", _x3p_increment("1e-300"), "increments in [1e-09, 1] m (tiny.x3p has x"),
    Case("vast.x3p", _x3p_increment("1e+300"), "increments in [1e-09, 1] m"),
    Case(
        "tall.x3p",
        lambda p: x3pio.write(p, np.full((8, 8), 2.0), x_scale=1e-5, y_scale=1e-5),
        "heights within ±1000 mm (tall.x3p holds heights from 2000 to 2000 mm)",
    ),
    Case("big.x3p", _big_x3p, "big.x3p declares 16384 x 16384 = 268435456 samples of float64"),
    Case("bomb.x3p", _x3p_bomb, "bomb.x3p's bindata/data.bin declares 32768 bytes from"),
    Case("overstated.x3p", _x3p_overstated, "declares 2147483648 bytes from 100 compressed"),
    Case("hugexml.x3p", _x3p_huge_xml, "hugexml.x3p declares a main.xml of 1024 MiB"),
    Case(
        "bzip.x3p",
        lambda p: _zip_bzip2(p),
        "members are stored or deflated (bzip.x3p's main.xml uses zip compression method 12)",
    ),
    # .tif
    Case("magic.tif", lambda p: p.write_bytes(b"II*\x01" + bytes(100)), "a readable height"),
    Case("truncated.tif", _tiff_truncated, "lie in the file"),
    Case("pages.tif", _multipage_tiff, "a TIFF of one page (pages.tif has 3)"),
    Case("rgb.tif", lambda p: tifffile.imwrite(p, np.zeros((8, 8, 3), np.uint8)), "a 2-D map"),
    Case("int.tif", lambda p: tifffile.imwrite(p, np.zeros((8, 8), np.int16)), "holds int16"),
    Case("half.tif", lambda p: tifffile.imwrite(p, np.zeros((8, 8), np.float16)), "float16"),
    Case("nan.tif", lambda p: tifffile.imwrite(p, np.full((8, 8), np.nan, np.float32)), "only NaN"),
    Case(
        "lzma.tif",
        lambda p: tifffile.imwrite(p, np.zeros((8, 8), np.float32), compression="lzma"),
        "an uncompressed or deflate (zlib) TIFF (lzma.tif is compressed with LZMA)",
    ),
    Case("big.tif", _big_tiff, "big.tif declares 16384 x 16384 = 268435456 samples of float32"),
    Case("bomb.tif", _tiff_bomb, "segment 0 holds more than 16385 bytes of samples"),
    Case("short.tif", _tiff_short, "segment 0 holds 1000 bytes of samples, its tags declare"),
    Case("hugetile.tif", _tiff_huge_tile, "strips or tiles are no larger than its image"),
    Case(
        "tinytiles.tif",
        lambda p: _tiff(p, 64, 64, zlib.compress(bytes(4)), tile=(1, 1)),
        "tiles are multiples of 16 samples a side (tinytiles.tif's are 1 x 1)",
    ),
    # .png
    Case("magic.png", lambda p: p.write_bytes(b"\x89PNX" + bytes(60)), "no PNG signature"),
    Case("eight.png", lambda p: cv2.imwrite(str(p), np.zeros((8, 8), np.uint8)), "8-bit grey"),
    Case(
        "rgb.png",
        lambda p: cv2.imwrite(str(p), np.zeros((8, 8, 3), np.uint16)),
        "(rgb.png is 16-bit with 3 channels)",
    ),
    Case("palette.png", lambda p: _png(p, 8, 8, b"", 8, 3), "8-bit with a palette"),
    Case(
        "line.png",
        lambda p: cv2.imwrite(str(p), np.zeros((1, 100), np.uint16)),
        "at least 4 x 4 samples (line.png has 1 rows x 100 columns)",
    ),
    Case("truncated.png", _png_truncated, "truncated.png's data inflates to"),
    Case(
        "big.png",
        lambda p: _png(p, SIDE, SIDE, zlib.compress(bytes(100))),
        "big.png declares 16384 x 16384 = 268435456 samples of uint16, 512 MiB",
    ),
    Case(
        "bomb.png",
        lambda p: _png(p, 64, 64, _deflated(bytes(MIB), 256, zlib_format=True)[0]),
        "bomb.png's data inflates to more than 8257 bytes, its header declares 8256",
    ),
    # special files
    Case("fifo.npy", lambda p: os.mkfifo(p), "(fifo.npy is a FIFO; glshade reads only regular"),
    Case("dir.npy", lambda p: p.mkdir(), "(dir.npy is a directory; glshade reads only regular"),
    Case("device.npy", lambda p: p.symlink_to("/dev/zero"), "is a character device; glshade"),
    Case("socket.npy", _socket, "(socket.npy is a socket; glshade reads only regular files)"),
    Case("missing.npy", None, "surface.file: must be an existing height map file"),
    Case("unreadable.npy", _unreadable, "a readable file (unreadable.npy: permission denied)"),
    Case("map.csv", lambda p: p.write_text("1,2"), "a height map file (.npy, .x3p"),
    # spacing, origin, scale
    Case(
        "m.npy",
        GOOD,
        "surface.spacing: must be two numbers [dx, dz] in [1e-06, 1000] mm, got 1e-300",
        "spacing = [1e-300, 1e-300]",
        id="spacing-tiny",
    ),
    Case(
        "m.npy",
        GOOD,
        "surface.spacing: must be two numbers [dx, dz] in [1e-06, 1000] mm, got 1e+300",
        "spacing = [1e300, 1e300]",
        id="spacing-vast",
    ),
    Case("m.npy", GOOD, "surface.spacing: must be", "spacing = [-1, 1]", id="spacing-negative"),
    Case("m.npy", GOOD, "spacing: must be a finite", "spacing = [nan, 1]", id="spacing-nan"),
    Case(
        "m.npy",
        GOOD,
        "surface.origin: must be two numbers [x, z] in [-10000, 10000] mm, got 1e+300",
        "origin = [1e300, 0]",
        id="origin-vast",
    ),
    Case(
        "m.npy",
        GOOD,
        "surface.scale: must be a number whose magnitude is in [1e-09, 1000]",
        "scale = 1e308",
        id="scale-vast",
    ),
    Case(
        "m.npy",
        GOOD,
        "surface.scale: must be a number whose magnitude is in [1e-09, 1000]",
        "scale = 1e-300",
        id="scale-tiny",
    ),
    Case(
        "m.npy",
        GOOD,
        "surface.scale: must be a scale that keeps the heights within ±1000 mm (m.npy holds",
        "scale = 999",
        id="scale-too-tall",
    ),
]


def _zip_bzip2(path: Path) -> None:
    import zipfile

    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_BZIP2) as archive:
        archive.writestr("main.xml", _main_xml(8, 8))


def _scene(case: Case) -> str:
    lines = ["[surface]", 'kind = "heightmap"', f'file = "{case.file}"']
    if "spacing" not in case.surface:
        lines.append("spacing = [0.1, 0.1]")
    return "\n".join([*lines, case.surface, ""])


def _listing(root: Path) -> dict[str, int]:
    return {str(p.relative_to(root)): p.lstat().st_size for p in sorted(root.rglob("*"))}


def _run(case: Case, folder: Path) -> subprocess.CompletedProcess:
    return run_glshade(
        "render", "scene.toml", "--size", "16", "-o", "out.png", cwd=folder, env=case.env
    )


@pytest.fixture(scope="module")
def hostile_results(tmp_path_factory):
    """Every case in a folder of its own, run two at a time; with the folder's listing
    before and after."""
    root = tmp_path_factory.mktemp("hostile_maps")
    folders = []
    for index, case in enumerate(CASES):
        folder = root / f"case{index}"
        folder.mkdir()
        if case.build is not None:
            case.build(folder / case.file)
        (folder / "scene.toml").write_text(_scene(case))
        folders.append(folder)
    before = [_listing(folder) for folder in folders]
    with ThreadPoolExecutor(max_workers=2) as pool:
        results = list(pool.map(_run, CASES, folders))
    return results, before, [_listing(folder) for folder in folders]


def test_the_table_covers_every_format_and_the_big_maps():
    names = [case.name for case in CASES]
    assert len(names) == len(set(names)) >= 60
    for suffix in (".npy", ".x3p", ".tif", ".png"):
        assert sum(name.endswith(suffix) for name in names) >= 8
        assert f"big{suffix}" in names


@pytest.mark.slow
@pytest.mark.parametrize("index", range(len(CASES)), ids=[case.name for case in CASES])
def test_a_hostile_map_is_one_line_exit_2_and_nothing_written(hostile_results, index):
    case = CASES[index]
    if case.build is _unreadable and os.geteuid() == 0:
        pytest.skip("root reads a file whatever its permissions")
    results, before, after = hostile_results
    result = results[index]
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2, result.stderr
    assert len(lines) == 1 and lines[0].startswith("glshade: error: "), result.stderr
    assert case.fragment in lines[0], lines[0]
    assert case.file.split(".")[0] in lines[0] or case.file == "m.npy", lines[0]
    assert result.stdout == ""
    assert after[index] == before[index]  # no out.png, nothing else


def test_the_big_files_are_small_on_disk(tmp_path):
    """The 16384² cases cost the test little: a sparse .npy, a 2 MB zip, a 33 KB TIFF."""
    _big_x3p(tmp_path / "big.x3p")
    _big_tiff(tmp_path / "big.tif")
    _sparse_npy(tmp_path / "big.npy", (SIDE, SIDE))
    assert (tmp_path / "big.x3p").stat().st_size < 3 * MIB
    assert (tmp_path / "big.tif").stat().st_size < 64 * 1024
    assert (tmp_path / "big.npy").stat().st_blocks * 512 < MIB  # a hole, where holes exist
