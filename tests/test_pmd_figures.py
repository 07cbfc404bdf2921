"""The figures ``glshade measure --method pmd --maps DIR`` writes: every file, legible
PNGs, colour scales that keep the dent and the sign, NaN drawn in its own grey."""

from __future__ import annotations

import numpy as np
import pytest

from glshade.files import read_png
from glshade.instruments.pmd.files import (
    DATA_FILES,
    MAP_FILES,
    NO_VALUE,
    dent_box,
    map_figure,
    map_images,
    map_scale,
    write_maps,
)
from glshade.instruments.pmd.model import station_model
from glshade.instruments.pmd.reconstruct import project
from glshade.instruments.pmd.station import measure_pmd
from glshade.measure.single import as_method
from glshade.scene import paper_scene


@pytest.fixture(scope="module")
def case():
    """A small dent (σ² 0.5 mm²) on the paper's flat plate, 128 px, a noisy sensor."""
    scene = as_method(paper_scene("flat", 45.0, 0.5, 0.005).with_size(128), "pmd")
    scene = scene.with_value("sensor.full_well_e", 10000)
    return scene, measure_pmd(scene)


def test_write_maps_writes_every_file_and_decodable_figures(case, tmp_path):
    scene, result = case
    written = write_maps(tmp_path, scene, result)
    assert sorted(p.name for p in written) == sorted(
        [f"{name}.{ext}" for name in MAP_FILES for ext in ("npy", "png")]
        + [f"{name}.npy" for name in DATA_FILES]
    )
    grey = np.round(np.array(NO_VALUE) * 255).astype(int)
    for name in MAP_FILES:
        pixels = read_png(tmp_path / f"{name}.png")
        height, width = pixels.shape[:2]
        assert 350 <= height <= 800 and 450 <= width <= 1500, (name, pixels.shape)
        assert pixels.std() > 10  # a picture, not a blank page
        if name == "height_um":  # NaN outside the height grid: its own grey, not a colour
            assert (np.abs(pixels[..., :3].astype(int) - grey).max(axis=-1) <= 1).sum() > 1000
    assert np.load(tmp_path / "height_um.npy").shape == (128, 128)


def test_signed_maps_have_symmetric_scales_and_magnitudes_keep_the_dent(case, tmp_path):
    scene, result = case
    views = map_images(scene, result)
    box = dent_box(scene, (128, 128))
    for name in ("height_um", "error_mm"):
        shown = views[name]
        values = np.concatenate([np.ravel(image) for _, image in shown.panels])
        lo, hi = map_scale(shown, values, box)
        assert lo == -hi and hi > 0, name
    # the height figure's scale: ± the largest height, per pixel or on the grid, the dent's
    # depth (dmax 5 µm, reconstructed) on the scale
    height = views["height_um"]
    lo, hi = map_figure(height, scene, result, tmp_path / "h.png")
    largest = max(
        np.nanmax(np.abs(result.maps.height_um)), np.nanmax(np.abs(result.maps.heights.height_um))
    )
    assert (lo, hi) == (-largest, largest) and hi == pytest.approx(5.0, rel=0.1)
    # the slope figure's scale reaches the dent's largest slope (the case's number)
    slopes = views["slopes"]
    _, top = map_scale(slopes, slopes.panels[0][1].ravel(), box)
    assert top >= result.pmd_slope_urad * (1 - 1e-6)


def test_the_zoom_window_holds_the_dent(case):
    """The dent's centre, projected through the camera, lies in the zoom's window, and
    the window is a small part of the frame (a σ² 0.5 mm² dent at 128 px)."""
    scene, _ = case
    box = dent_box(scene, (128, 128))
    assert box is not None
    r0, r1, c0, c1 = box
    d = scene.defect
    centre = np.array([d.x0, float(scene.active.surface.height(scene, d.x0, d.z0)), d.z0])
    row, col = (float(v) for v in project(station_model(scene), centre))
    assert r0 <= row <= r1 and c0 <= col <= c1
    assert (r1 - r0 + 1) * (c1 - c0 + 1) < 0.25 * 128 * 128
