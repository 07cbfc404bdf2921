"""Reading height maps: every format's layout and units, the scale, the cache, and every
refusal (one line, naming ``surface.file``, the file and the problem)."""

from __future__ import annotations

import hashlib
import os
import socket
import struct
import zipfile
import zlib
from pathlib import Path

import cv2
import numpy as np
import pytest
import tifffile
import x3pio

from glshade.components.surface.heightmap import readers as heightmap_io
from glshade.components.surface.heightmap.readers import (
    HeightMap,
    cached_height_map,
    load_height_map,
    read_height_map,
)
from glshade.errors import SceneError

# 5 rows (along z) x 6 columns (along x), every sample different: an orientation check.
MAP = np.arange(30, dtype=np.float64).reshape(5, 6) * 0.001


def test_npy_in_any_real_dtype(tmp_path):
    for dtype in (np.float64, np.float32, np.int16, np.uint8):
        np.save(tmp_path / "m.npy", (MAP * 1000).astype(dtype))
        got = read_height_map(tmp_path / "m.npy", scale=0.001)
        assert isinstance(got, HeightMap) and got.source == str(tmp_path / "m.npy")
        assert (
            got.heights.dtype == np.float64
            and got.heights.shape == (5, 6)
            and got.spacing_mm is None
        )
        assert got.heights == pytest.approx(MAP, abs=1e-9)


def test_the_scale_is_mm_per_stored_unit(tmp_path):
    np.save(tmp_path / "m.npy", MAP.astype(np.float32))
    assert read_height_map(tmp_path / "m.npy").heights == pytest.approx(MAP, abs=1e-7)
    assert read_height_map(tmp_path / "m.npy", scale=-2.5).heights == pytest.approx(
        -2.5 * MAP, abs=1e-6
    )


def test_x3p_is_metres_with_x_along_columns_and_y_along_rows(tmp_path):
    x3pio.write(tmp_path / "m.x3p", MAP * 1e-3, x_scale=20e-6, y_scale=30e-6)  # metres
    # The file itself: SizeX counts the 6 columns, SizeY the 5 rows, x varies fastest.
    xml = zipfile.ZipFile(tmp_path / "m.x3p").read("main.xml").decode()
    assert "<SizeX>6</SizeX>" in xml and "<SizeY>5</SizeY>" in xml
    got = read_height_map(
        tmp_path / "m.x3p", scale=123.0
    )  # the scale does not apply: the file has units
    assert got.heights.shape == (5, 6)
    assert got.heights == pytest.approx(MAP, rel=1e-12)  # [row, column] = [y index, x index]
    assert got.heights[0, 1] == pytest.approx(0.001) and got.heights[1, 0] == pytest.approx(0.006)
    assert got.spacing_mm == pytest.approx((0.02, 0.03))  # (x between columns, z between rows)


def test_unmeasured_points_are_kept_as_nan(tmp_path):
    """Profilometers write NaN where they measured nothing: .x3p and .npy maps with NaN
    patches load, the NaN where the file has them (other formats alike)."""
    holed = MAP.copy()
    holed[1:3, 2:4] = np.nan
    holed[4, 0] = np.nan
    x3pio.write(tmp_path / "m.x3p", holed * 1e-3, x_scale=20e-6, y_scale=30e-6)
    np.save(tmp_path / "m.npy", holed)
    for name in ("m.x3p", "m.npy"):
        got = read_height_map(tmp_path / name).heights
        assert np.array_equal(np.isnan(got), np.isnan(holed)), name
        finite = ~np.isnan(holed)
        assert got[finite] == pytest.approx(MAP[finite], rel=1e-12), name


def test_float_tiff_and_16_bit_png(tmp_path):
    tifffile.imwrite(tmp_path / "m.tif", MAP.astype(np.float32))
    got = read_height_map(tmp_path / "m.tif")
    assert got.heights.dtype == np.float64 and got.spacing_mm is None
    assert got.heights == pytest.approx(MAP, abs=1e-7)
    tifffile.imwrite(tmp_path / "m.TIFF", (MAP * 1e4).astype(np.uint16))  # any case
    assert read_height_map(tmp_path / "m.TIFF", scale=1e-4).heights == pytest.approx(MAP, abs=1e-9)
    cv2.imwrite(str(tmp_path / "m.png"), (MAP * 1e4).astype(np.uint16))
    got = read_height_map(tmp_path / "m.png", scale=1e-4)
    assert got.heights == pytest.approx(MAP, abs=1e-9) and got.spacing_mm is None


def test_maps_are_read_only_and_compared_by_identity(tmp_path):
    np.save(tmp_path / "m.npy", MAP)
    a, b = read_height_map(tmp_path / "m.npy"), read_height_map(tmp_path / "m.npy")
    assert a != b and len({a, b, a}) == 2  # identity: hashable, never compares the arrays
    with pytest.raises(ValueError):
        a.heights[0, 0] = 1.0
    assert "heights" not in repr(a)


def test_a_changed_file_is_read_again(tmp_path):
    path = tmp_path / "m.npy"
    np.save(path, MAP)
    load_height_map.cache_clear()
    first = cached_height_map(path)
    assert cached_height_map(path) is first and cached_height_map(str(path)) is first
    assert cached_height_map(path, scale=2.0) is not first
    np.save(path, np.vstack([MAP, MAP]))  # another size, so another key whatever the clock
    again = cached_height_map(path)
    assert again is not first and again.heights.shape == (10, 6)
    assert load_height_map.cache_info().hits == 2


def test_a_missing_file_is_not_cached(tmp_path):
    with pytest.raises(SceneError, match="an existing height map file"):
        cached_height_map(tmp_path / "later.npy")
    np.save(tmp_path / "later.npy", MAP)
    assert cached_height_map(tmp_path / "later.npy").heights.shape == (5, 6)


def _nan_at(row, col):
    bad = MAP.copy()
    bad[row, col] = np.nan
    bad[4, 5] = np.inf
    return bad


def _x3p_with_x_increment(path, increment):
    """An x3p whose x increment x3pio would not write (checksum made to match)."""
    x3pio.write(path.with_suffix(".tmp"), MAP * 1e-3, x_scale=20e-6, y_scale=30e-6)
    src = zipfile.ZipFile(path.with_suffix(".tmp"))
    xml = (
        src.read("main.xml")
        .decode()
        .replace("<Increment>2e-05</Increment>", f"<Increment>{increment}</Increment>")
    )
    with zipfile.ZipFile(path, "w") as out:
        out.writestr("main.xml", xml)
        out.writestr("md5checksum.hex", hashlib.md5(xml.encode()).hexdigest() + " *main.xml\n")
        for name in src.namelist():
            if name.startswith("bindata/"):
                out.writestr(name, src.read(name))


REFUSALS = [
    ("missing.npy", None, "an existing height map file"),
    ("m.csv", lambda p: p.write_text("1,2"), "a height map file (.npy, .x3p, .tif, .tiff, .png)"),
    ("noext", lambda p: p.write_text("1,2"), "a height map file (.npy"),
    (
        "dir.npy",
        lambda p: p.mkdir(),
        "a regular file (dir.npy is a directory; glshade reads only regular files)",
    ),
    (
        "corrupt.npy",
        lambda p: p.write_bytes(b"\x93NUMPY garbage"),
        "a readable height map (corrupt.npy: ",
    ),
    ("empty.npy", lambda p: p.write_bytes(b""), "a readable height map (empty.npy: "),
    (
        "short.npy",
        lambda p: p.write_bytes(_npy_bytes(np.zeros((50, 50)))[:200]),
        "(short.npy's header declares 20000 bytes of samples, the file holds 72)",
    ),
    (
        "corrupt.x3p",
        lambda p: p.write_bytes(b"PK\x03\x04 not a zip"),
        "a readable height map (corrupt.x3p: ",
    ),
    (
        "corrupt.tif",
        lambda p: p.write_bytes(b"II*\x00garbage"),
        "a TIFF of one page (corrupt.tif has none)",
    ),
    (
        "corrupt.png",
        lambda p: p.write_bytes(b"\x89PNG\r\n\x1a\n garbage"),
        "a readable PNG (corrupt.png",
    ),
    (
        "complex.npy",
        lambda p: np.save(p, MAP.astype(complex)),
        "real integers or floats (complex.npy holds complex128)",
    ),
    ("bool.npy", lambda p: np.save(p, MAP > 0.01), "real integers or floats (bool.npy holds bool)"),
    (
        "object.npy",
        lambda p: np.save(p, MAP.astype(object), allow_pickle=True),
        "(object.npy holds object)",
    ),
    (
        "struct.npy",
        lambda p: np.save(p, np.zeros((5, 5), [("a", "f8"), ("b", "f8")])),
        "real integers or floats",
    ),
    (
        "cube.npy",
        lambda p: np.save(p, np.zeros((4, 4, 4))),
        "a 2-D map, rows x columns (cube.npy has shape (4, 4, 4))",
    ),
    ("line.npy", lambda p: np.save(p, np.zeros(16)), "a 2-D map"),
    (
        "small.npy",
        lambda p: np.save(p, np.zeros((3, 8))),
        "at least 4 x 4 samples (small.npy has 3 rows x 8 columns)",
    ),
    (
        "inf.npy",
        lambda p: np.save(p, _nan_at(1, 2)),
        "(inf.npy has 1 Inf sample, the first at row 4, column 5; NaN marks an unmeasured",
    ),
    (
        "inf.tif",
        lambda p: tifffile.imwrite(p, np.full((5, 5), -np.inf, np.float32)),
        "25 Inf samples",
    ),
    (
        "unmeasured.x3p",
        lambda p: x3pio.write(p, np.full((5, 6), np.nan), x_scale=1e-5, y_scale=1e-5),
        "a height map with a measured sample (unmeasured.x3p holds only NaN",
    ),
    (
        "unmeasured.npy",
        lambda p: np.save(p, np.full((5, 6), np.nan)),
        "(unmeasured.npy holds only NaN: unmeasured)",
    ),
    (
        "rgb.png",
        lambda p: cv2.imwrite(str(p), np.zeros((5, 5, 3), np.uint16)),
        "(rgb.png is 16-bit with 3 channels)",
    ),
    (
        "eight.png",
        lambda p: cv2.imwrite(str(p), np.zeros((5, 5), np.uint8)),
        "(eight.png is 8-bit greyscale)",
    ),
    (
        "int.tif",
        lambda p: tifffile.imwrite(p, np.zeros((5, 5), np.int16)),
        "unsigned integers (int.tif holds int16)",
    ),
    (
        "half.tif",
        lambda p: tifffile.imwrite(p, np.zeros((5, 5), np.float16)),
        "(half.tif holds float16)",
    ),
    ("rgb.tif", lambda p: tifffile.imwrite(p, np.zeros((5, 5, 3), np.uint8)), "a 2-D map"),
    (
        "profile.x3p",
        lambda p: x3pio.write(p, np.zeros(10), x_scale=1e-5),
        "(profile.x3p holds a profile)",
    ),
    (
        "cloud.x3p",
        lambda p: x3pio.write_points(p, np.random.default_rng(1).uniform(0, 1e-3, (20, 3))),
        "(cloud.x3p holds a pointcloud)",
    ),
    (
        "irregular.x3p",
        lambda p: x3pio.Surface.from_points(_irregular_points()).save(p),
        "(irregular.x3p is a non-regular grid",
    ),
    (
        "backwards.x3p",
        lambda p: _x3p_with_x_increment(p, "-2e-05"),
        "increments in [1e-09, 1] m (backwards.x3p has x increment -2e-05 m, y increment 3e-05 m)",
    ),
    ("zero.x3p", lambda p: _x3p_with_x_increment(p, "0.0"), "a readable height map (zero.x3p: "),
    ("line\nbreak.npy", lambda p: np.save(p, np.zeros((2, 8))), "line\\nbreak.npy has 2 rows"),
]


def _npy_bytes(array):
    import io

    buf = io.BytesIO()
    np.save(buf, array)
    return buf.getvalue()


def _irregular_points():
    x, y = np.meshgrid(np.arange(6) * 1e-5, np.arange(5) * 1e-5)
    x = x + np.random.default_rng(2).uniform(0, 3e-6, x.shape)  # jittered: not a regular grid
    return np.stack([x, y, np.zeros_like(x)], axis=-1)


@pytest.mark.parametrize(("name", "writer", "fragment"), REFUSALS, ids=[r[0] for r in REFUSALS])
def test_refusals_are_one_line_naming_the_file(tmp_path, monkeypatch, name, writer, fragment):
    monkeypatch.chdir(tmp_path)  # named as typed, short: a long path is shortened in the line
    path = Path(name)
    if writer is not None:
        writer(path)
    with pytest.raises(SceneError) as info:
        read_height_map(path)
    message = str(info.value)
    assert info.value.field == "surface.file"
    assert message.startswith("surface.file: must be ") and "\n" not in message
    assert fragment in message, message
    assert name.replace("\n", "\\n") in message, message


def test_the_largest_side(tmp_path, monkeypatch):
    np.save(tmp_path / "m.npy", np.zeros((5, 6)))
    monkeypatch.setattr(heightmap_io, "MAX_SIDE", 6)
    assert read_height_map(tmp_path / "m.npy").heights.shape == (5, 6)
    monkeypatch.setattr(heightmap_io, "MAX_SIDE", 5)
    with pytest.raises(
        SceneError, match=r"at most 5 samples a side \(m.npy has 5 rows x 6 columns\)"
    ):
        read_height_map(tmp_path / "m.npy")
    x3pio.write(tmp_path / "m.x3p", np.zeros((6, 5)), x_scale=1e-5, y_scale=1e-5)
    with pytest.raises(
        SceneError, match=r"at most 5 samples a side \(m.x3p has 6 rows x 5 columns\)"
    ):
        read_height_map(tmp_path / "m.x3p")


def test_heights_beyond_a_metre_are_refused_before_scaling(tmp_path):
    """The heights after ``scale`` must lie within ±1000 mm: checked on the stored extremes
    before multiplying, so nothing overflows (1e308 used to, with NumPy's warnings)."""
    np.save(tmp_path / "m.npy", MAP + 10.0)  # 10 to 10.029 stored units
    assert read_height_map(tmp_path / "m.npy", scale=99.0).heights.max() == pytest.approx(992.871)
    with pytest.raises(SceneError) as info:
        read_height_map(tmp_path / "m.npy", scale=1e308)
    assert str(info.value) == (
        "surface.scale: must be a scale that keeps the heights within ±1000 mm (m.npy holds "
        "heights from 10 to 10.029 stored units; times 1e+308 they reach inf mm)"
    )
    with pytest.raises(SceneError, match="times -100 they reach 1002.9 mm"):
        read_height_map(tmp_path / "m.npy", scale=-100.0)
    with pytest.raises(SceneError, match="surface.scale: must be a finite non-zero number"):
        read_height_map(tmp_path / "m.npy", scale=float("nan"))
    x3pio.write(tmp_path / "tall.x3p", np.full((5, 6), 1.5), x_scale=1e-5, y_scale=1e-5)
    with pytest.raises(SceneError, match=r"heights within ±1000 mm \(tall.x3p holds heights"):
        read_height_map(tmp_path / "tall.x3p")


def test_the_example_panel_reads():
    panel = read_height_map(Path(__file__).resolve().parents[1] / "examples" / "panel.x3p")
    rows, cols = panel.heights.shape
    assert rows == cols and panel.spacing_mm == pytest.approx((0.1, 0.1))
    # Convex: the centre is the highest region, the corners the lowest.
    assert panel.heights[rows // 2, cols // 2] > panel.heights[0, 0] + 0.1
    # Curvature about 1/2500 along x (columns) and 1/1800 along z (rows): the z edge is lower.
    assert panel.heights[0, cols // 2] < panel.heights[rows // 2, 0]


# ------------------------------------------------------------------ hostile files
def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def _png16(heights: np.ndarray, interlace: int = 0, filter_type: int = 0, extra: bytes = b""):
    """A 16-bit greyscale PNG written by hand (Adam7 passes when interlaced; every row
    of filter ``filter_type`` with its bytes unfiltered); ``extra`` chunks after IHDR."""
    rows, cols = heights.shape
    passes = heightmap_io._ADAM7 if interlace else ((0, 0, 1, 1),)
    raw = b"".join(
        bytes([filter_type]) + row.astype(">u2").tobytes()
        for column, row0, column_step, row_step in passes
        for row in heights[row0::row_step, column::column_step]
        if row.size
    )
    header = struct.pack(">IIBBBBB", cols, rows, 16, 0, 0, 0, interlace)
    return (
        b"\x89PNG\r\n\x1a\n"
        + _png_chunk(b"IHDR", header)
        + extra
        + _png_chunk(b"IDAT", zlib.compress(raw))
        + _png_chunk(b"IEND", b"")
    )


@pytest.mark.parametrize("shape", [(4, 4), (7, 13), (9, 5), (33, 64)])
def test_interlaced_and_plain_16_bit_pngs_read_as_opencv_reads_them(tmp_path, shape):
    stored = np.random.default_rng(sum(shape)).integers(0, 65535, shape).astype(np.uint16)
    for interlace in (0, 1):
        path = tmp_path / f"m{interlace}.png"
        path.write_bytes(_png16(stored, interlace))
        assert np.array_equal(cv2.imread(str(path), cv2.IMREAD_UNCHANGED), stored)
        assert np.array_equal(read_height_map(path, scale=1e-5).heights, stored * 1e-5)


def test_libpng_never_writes_to_stderr(tmp_path, capfd):
    """A damaged ancillary chunk made libpng print a warning of its own on stderr: the
    decoder is now handed only IHDR, IDAT and IEND, their CRCs and filter bytes checked."""
    stored = np.arange(64, dtype=np.uint16).reshape(8, 8)
    bad_text = struct.pack(">I", 5) + b"tEXt" + b"a\x00bcd" + bytes(4)  # a wrong CRC
    (tmp_path / "text.png").write_bytes(_png16(stored, extra=bad_text))
    assert np.array_equal(read_height_map(tmp_path / "text.png").heights, stored)
    (tmp_path / "filter.png").write_bytes(_png16(stored, filter_type=5))
    with pytest.raises(SceneError, match=r"\(filter.png has a row whose filter type is not 0"):
        read_height_map(tmp_path / "filter.png")
    damaged = bytearray(_png16(stored))
    damaged[-14] ^= 0xFF  # in the IDAT chunk's CRC (IEND takes the last 12 bytes)
    (tmp_path / "crc.png").write_bytes(bytes(damaged))
    with pytest.raises(SceneError, match=r"\(crc.png's image data fails its CRC\)"):
        read_height_map(tmp_path / "crc.png")
    critical = _png_chunk(b"ABCD", b"x")
    (tmp_path / "critical.png").write_bytes(_png16(stored, extra=critical))
    with pytest.raises(SceneError, match=r"\(critical.png has a critical chunk b'ABCD'\)"):
        read_height_map(tmp_path / "critical.png")
    assert capfd.readouterr().err == ""


TIFF_LAYOUTS = [
    {},
    {"compression": "zlib"},
    {"compression": "adobe_deflate"},
    {"rowsperstrip": 5},
    {"rowsperstrip": 5, "compression": "zlib"},
    {"tile": (16, 32), "compression": "zlib"},
    {"tile": (16, 16)},
    {"byteorder": ">"},
    {"bigtiff": True, "compression": "zlib"},
]


@pytest.mark.parametrize("dtype", [np.float32, np.float64, np.uint8, np.uint16, np.uint32])
def test_every_tiff_layout_reads_back_exactly(tmp_path, dtype):
    """Strips, tiles (not dividing the image), deflate, the horizontal predictor,
    big-endian and BigTIFF files pass the segment checks and read back exactly."""
    stored = np.random.default_rng(0).uniform(0, 200, (37, 53)).astype(dtype)
    integers = np.dtype(dtype).kind == "u"  # the predictor of floats needs imagecodecs
    layouts = TIFF_LAYOUTS + [{"compression": "zlib", "predictor": True}] * integers
    for layout in layouts:
        tifffile.imwrite(tmp_path / "m.tif", stored, **layout)
        heights = read_height_map(tmp_path / "m.tif").heights
        assert np.array_equal(heights, stored.astype(np.float64)), layout


def test_the_memory_budget_counts_56_bytes_a_sample(tmp_path, monkeypatch):
    """1 MiB holds 18724 samples at 56 bytes: 4 x 4681 loads, 4 x 4682 is refused
    before its data is read (the file holds none)."""
    monkeypatch.setenv("GLSHADE_MEMORY_BUDGET_MB", "1")
    assert heightmap_io.BYTES_PER_SAMPLE == 56
    np.save(tmp_path / "fits.npy", np.zeros((4, 4681), np.float32))
    assert read_height_map(tmp_path / "fits.npy").heights.shape == (4, 4681)
    with open(tmp_path / "over.npy", "wb") as f:  # a header only: nothing to decode
        np.lib.format.write_array_header_1_0(
            f, {"descr": "<f4", "fortran_order": False, "shape": (4, 4682)}
        )
    with pytest.raises(SceneError) as info:
        read_height_map(tmp_path / "over.npy")
    assert str(info.value) == (
        "surface.file: must be a map that loads within the memory budget "
        "(GLSHADE_MEMORY_BUDGET_MB = 1 MiB at 56 bytes a sample: at most 18724 samples; "
        "over.npy declares 4 x 4682 = 18728 samples of float32, 0.0714 MiB in the file, "
        "1 MiB loaded)"
    )


def test_a_npy_whose_data_outgrows_its_header_is_refused(tmp_path):
    (tmp_path / "m.npy").write_bytes(_npy_bytes(np.zeros((5, 6))) + bytes(8))
    with pytest.raises(SceneError, match=r"declares 240 bytes of samples, the file holds 248"):
        read_height_map(tmp_path / "m.npy")


def test_special_files_are_refused_by_their_type(tmp_path):
    """Looked up before opening: a FIFO (opening it would wait for a writer), a device,
    a socket; none of them is opened."""
    os.mkfifo(tmp_path / "fifo.npy")
    (tmp_path / "zero.npy").symlink_to("/dev/zero")
    with socket.socket(socket.AF_UNIX) as server:
        server.bind(str(tmp_path / "sock.npy"))
    for name, kind in (("fifo", "a FIFO"), ("zero", "a character device"), ("sock", "a socket")):
        with pytest.raises(SceneError) as info:
            cached_height_map(tmp_path / f"{name}.npy")
        assert str(info.value) == (
            f"surface.file: must be a regular file ({name}.npy is {kind}; glshade reads only "
            "regular files)"
        )
