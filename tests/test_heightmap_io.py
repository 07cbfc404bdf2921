"""Reading height maps: every format's layout and units, the cache, and every refusal."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
import tifffile
import x3pio

from glshade import heightmap_io
from glshade.errors import SceneError
from glshade.heightmap_io import cached_height_map, read_height_map

MAP = np.arange(30, dtype=np.float64).reshape(5, 6) * 0.001  # 5 rows (z) x 6 columns (x)


def test_npy_in_any_real_dtype(tmp_path):
    for dtype in (np.float64, np.float32, np.int16):
        np.save(tmp_path / "m.npy", (MAP * 1000).astype(dtype))
        got = read_height_map(tmp_path / "m.npy", scale=0.001)
        assert got.heights.dtype == np.float64 and got.spacing_mm is None
        assert got.heights == pytest.approx(MAP, abs=1e-9)


def test_x3p_carries_metres_and_its_grid(tmp_path):
    x3pio.write(tmp_path / "m.x3p", MAP * 1e-3, x_scale=20e-6, y_scale=30e-6)  # metres
    got = read_height_map(tmp_path / "m.x3p", scale=123.0)  # the scale does not apply: the file has units
    assert got.heights.shape == (5, 6)  # x3p SizeX = 6 columns along x, SizeY = 5 rows along z
    assert got.heights == pytest.approx(MAP, rel=1e-12)
    assert got.spacing_mm == pytest.approx((0.02, 0.03))


def test_float_tiff_and_16_bit_png(tmp_path):
    tifffile.imwrite(tmp_path / "m.tif", MAP.astype(np.float32))
    assert read_height_map(tmp_path / "m.tif").heights == pytest.approx(MAP, abs=1e-7)
    cv2.imwrite(str(tmp_path / "m.png"), (MAP * 1e4).astype(np.uint16))
    assert read_height_map(tmp_path / "m.png", scale=1e-4).heights == pytest.approx(MAP, abs=1e-9)


def test_a_changed_file_is_read_again(tmp_path):
    path = tmp_path / "m.npy"
    np.save(path, MAP)
    first = cached_height_map(path)
    assert cached_height_map(path) is first
    np.save(path, MAP * 2 + np.zeros((5, 6)))
    assert cached_height_map(path).heights == pytest.approx(MAP * 2)


def _bad(tmp_path, name, writer):
    path = tmp_path / name
    writer(path)
    return path


@pytest.mark.parametrize("name, writer, fragment", [
    ("missing.npy", None, "an existing height map file"),
    ("m.csv", lambda p: p.write_text("1,2"), "a height map file (.npy, .x3p"),
    ("dir.npy", lambda p: p.mkdir(), "not a directory"),
    ("corrupt.npy", lambda p: p.write_bytes(b"\x93NUMPY garbage"), "a readable height map (corrupt.npy"),
    ("corrupt.x3p", lambda p: p.write_bytes(b"PK\x03\x04 not a zip"), "a readable height map (corrupt.x3p"),
    ("complex.npy", lambda p: np.save(p, MAP.astype(complex)), "real numbers"),
    ("bool.npy", lambda p: np.save(p, MAP > 0.01), "real numbers"),
    ("cube.npy", lambda p: np.save(p, np.zeros((4, 4, 4))), "a 2-D map"),
    ("small.npy", lambda p: np.save(p, np.zeros((3, 8))), "at least 4 x 4 samples (small.npy has 3 x 8)"),
    ("nan.npy", lambda p: np.save(p, np.where(np.arange(30).reshape(5, 6) == 8, np.nan, MAP)),
     "1 NaN or Inf samples, the first at row 1, column 2"),
    ("inf.tif", lambda p: tifffile.imwrite(p, np.full((5, 5), np.inf, np.float32)), "25 NaN or Inf"),
    ("rgb.png", lambda p: cv2.imwrite(str(p), np.zeros((5, 5, 3), np.uint8)), "a 16-bit greyscale PNG"),
    ("eight.png", lambda p: cv2.imwrite(str(p), np.zeros((5, 5), np.uint8)), "a 16-bit greyscale PNG"),
    ("int.tif", lambda p: tifffile.imwrite(p, np.zeros((5, 5), np.int16)), "a float or unsigned integer TIFF"),
])
def test_refusals_are_one_line_naming_the_file(tmp_path, name, writer, fragment):
    path = tmp_path / name if writer is None else _bad(tmp_path, name, writer)
    with pytest.raises(SceneError) as info:
        read_height_map(path)
    message = str(info.value)
    assert message.startswith("surface.file: must be") and "\n" not in message
    assert fragment in message, message


def test_a_non_regular_x3p_grid_is_refused(tmp_path):
    points = np.column_stack([np.random.default_rng(1).uniform(0, 1e-3, (20, 2)), np.zeros(20)])
    x3pio.write_points(tmp_path / "cloud.x3p", points)
    with pytest.raises(SceneError, match="regular grid"):
        read_height_map(tmp_path / "cloud.x3p")


def test_the_largest_side(tmp_path, monkeypatch):
    monkeypatch.setattr(heightmap_io, "MAX_SIDE", 5)
    np.save(tmp_path / "m.npy", np.zeros((5, 6)))
    with pytest.raises(SceneError, match="at most 5 samples a side"):
        read_height_map(tmp_path / "m.npy")


def test_the_example_panel_reads():
    from pathlib import Path

    panel = read_height_map(Path(__file__).resolve().parents[1] / "examples" / "panel.x3p")
    assert panel.heights.shape == (640, 640) and panel.spacing_mm == pytest.approx((0.1, 0.1))
    peel = panel.heights - panel.heights.mean()
    assert 1e-4 < np.abs(peel).max() < 2.0
