from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("h5py")

from glshade.capture.sofast import read_sofast_calibration, read_sofast_measurement


def test_reader_frames_and_masks(sofast_dir) -> None:
    m = read_sofast_measurement(sofast_dir / "measurement_facet.h5")
    assert m.frames.shape == (32, 154, 203)
    assert m.black.shape == m.white.shape == (154, 203)
    assert m.shifts == 4
    assert m.periods_x == (0.9, 3.9, 15.9, 63.9)
    assert m.white.mean() > m.black.mean()
    assert abs(m.dist_optic_screen_mm - 10232.0) < 1.0


def test_calibration_reader(sofast_dir) -> None:
    c = read_sofast_calibration(sofast_dir / "image_calibration.h5")
    assert c.camera_values.shape == c.display_values.shape == (27,)
    out = c.response(np.array([[0, 128, 255]], dtype=np.uint8))
    assert out.shape == (1, 3) and np.all(np.isfinite(out))


def _expected(folder: Path) -> tuple[np.ndarray, np.ndarray]:
    import h5py

    with h5py.File(folder / "expected_facet.h5", "r") as h5:
        g = h5["DataSofastCalculation/facet/facet_000"]
        mask = g["CalculationImageProcessingFacet/mask_processed"][()].astype(bool)
        frac = g["CalculationDataGeometryFacet/v_screen_points_fractional_screens"][()]
    return mask, frac


def test_decode_matches_sofast_calibrated_and_raw(sofast_dir) -> None:
    from glshade.capture.sofast import decode_sofast

    d = sofast_dir
    m = read_sofast_measurement(d / "measurement_facet.h5")
    c = read_sofast_calibration(d / "image_calibration.h5")
    mask, frac = _expected(sofast_dir)
    assert mask.sum() == 7105
    rms = {}
    for name, cal in (("cal", c), ("raw", None)):
        r = decode_sofast(m, cal)
        diffs = [r.x[mask] - frac[0], r.y[mask] - frac[1]]
        ok = np.isfinite(diffs[0]) & np.isfinite(diffs[1])
        assert ok.sum() >= 7105 - 10
        for dd in diffs:
            assert np.max(np.abs(dd[ok])) < 1e-3  # no pixel on another fringe
        rms[name] = max(float(np.sqrt(np.mean(dd[ok] ** 2))) for dd in diffs)
        assert np.all(np.isfinite(r.residual_x[mask])) and np.all(np.isfinite(r.residual_y[mask]))
    assert rms["cal"] <= 1e-6
    assert rms["raw"] > rms["cal"]


def test_the_decode_command_on_a_sofast_measurement(tmp_path, capsys, sofast_dir) -> None:
    """glshade decode on the real measurement with its calibration record and screen
    shape: its fractions are SOFAST's to 1e-6 rms (measured 3.3e-8), its screen points
    SOFAST's, and the summary says the data support decoding without the curve."""
    import json

    from glshade.app.cli import main

    d = sofast_dir
    out = tmp_path / "dec"
    args = ["decode", str(d / "measurement_facet.h5"), "--out", str(out)]
    args += ["--response", str(d / "image_calibration.h5")]
    args += ["--display", str(d / "display_distorted_2d.h5")]
    assert main(args) == 0
    mask, frac = _expected(sofast_dir)
    maps = np.load(out / "maps.npz")
    ok = maps["valid"][mask]
    assert ok.sum() == 7105 - 7  # the finest y fringe is blurred on 7 edge pixels
    for axis in (0, 1):
        diff = maps["fraction"][..., axis][mask][ok] - frac[axis][ok]
        assert np.sqrt(np.mean(diff**2)) <= 1e-6
    import h5py

    with h5py.File(d / "expected_facet.h5", "r") as h5:
        geo = h5["DataSofastCalculation/facet/facet_000/CalculationDataGeometryFacet"]
        screen = 1000 * geo["v_screen_points_screen"][()]
    diff = maps["screen_mm"][mask][ok] - screen.T[ok]
    assert np.abs(diff).max() < 1e-3  # mm on an 8.7 m screen
    summary = json.loads((out / "summary.json").read_text())
    check = summary["response_check"]
    assert check["supported"] == "without" and "without the response" in check["verdict"]
    ratios = check["residual_over_modulation"]
    assert max(ratios["without"].values()) < 0.5 * min(ratios["with"].values())
    assert summary["region_pixels"] >= 7105
    assert "support decoding without" in (out / "summary.md").read_text()


def test_the_fallback_rule_keeps_the_blurred_edge_pixels(tmp_path, sofast_dir) -> None:
    """--rule fallback: the 7 facet-edge pixels whose finest y fringe is below the
    threshold are decoded from the next period, and said to be."""
    from glshade.app.cli import main

    d = sofast_dir
    out = tmp_path / "fb"
    args = ["decode", str(d / "measurement_facet.h5"), "--out", str(out), "--rule", "fallback"]
    assert main([*args, "--response", str(d / "image_calibration.h5")]) == 0
    mask, frac = _expected(sofast_dir)
    maps = np.load(out / "maps.npz")
    assert maps["valid"][mask].all()
    used = maps["finest_used"][1][mask]
    assert (used == 1).sum() == 7 and (used == 0).sum() == 7105 - 7
    assert not maps["period_valid"][1, 0][mask][used == 1].any()
    coarse = used == 1
    assert np.abs(maps["fraction"][..., 1][mask][coarse] - frac[1][coarse]).max() < 2e-3
    assert np.all(maps["noise_mm"][1][mask][coarse] > np.median(maps["noise_mm"][1][mask][~coarse]))


def test_a_file_that_is_not_a_measurement_is_one_line(tmp_path, capsys, sofast_dir) -> None:
    from glshade.app.cli import main

    d = sofast_dir
    out = tmp_path / "x"
    assert main(["decode", str(d / "camera_sofast_downsampled.h5"), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "MeasurementSofastFringe" in err
    (tmp_path / "junk.h5").write_text("not hdf5")
    assert main(["decode", str(tmp_path / "junk.h5"), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "not a readable HDF5" in err
    assert not out.exists()


def test_a_sofast_file_round_trips(tmp_path, sofast_dir) -> None:
    """Read, written, read again: every dataset the same as the original file's; a
    capture in SOFAST's conventions converts back; one that is not says so."""
    import h5py

    from glshade.capture.sofast import (
        measurement_of,
        read_sofast_capture,
        write_sofast_measurement,
    )

    original = sofast_dir / "measurement_facet.h5"
    m = read_sofast_measurement(original)
    assert m.name == "NSTTF Heliostat Facet" and m.measure_point_mm == (0.0, 0.0, 0.0)
    write_sofast_measurement(tmp_path / "again.h5", m)
    with h5py.File(original, "r") as a, h5py.File(tmp_path / "again.h5", "r") as b:
        ga, gb = a["MeasurementSofastFringe"], b["MeasurementSofastFringe"]
        assert set(ga) == set(gb)
        for key in ga:
            va, vb = ga[key][()], gb[key][()]
            if isinstance(va, bytes):
                assert va == vb, key
            else:
                assert np.array_equal(va, vb) and np.asarray(va).dtype == np.asarray(vb).dtype, key
    capture = read_sofast_capture(original)
    back = measurement_of(capture, m.dist_optic_screen_mm)
    assert np.array_equal(back.frames, m.frames) and np.array_equal(back.white, m.white)
    assert back.periods_x == m.periods_x and back.direction_order == m.direction_order
    from dataclasses import replace

    from glshade.errors import GlshadeError

    turned = replace(capture, coding=replace(capture.coding, shift_sign=-1))
    with pytest.raises(GlshadeError, match="not in SOFAST's conventions"):
        measurement_of(turned, 1000.0)
