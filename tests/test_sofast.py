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
    assert summary["status"] == "ok"
    check = summary["response_check"]
    assert check["supported"] == "without" and "without the response" in check["verdict"]
    ratios = check["residual_over_modulation"]
    assert max(ratios["without"].values()) < 0.5 * min(ratios["with"].values())
    shares = check["residual_share"]
    assert set(shares["with"]) == set(shares["without"]) == {"u", "v"}
    assert max(shares["without"].values()) < min(shares["with"].values())
    assert summary["peak"] == 255.0 and summary["threshold"] == 12.75
    assert 0 < summary["lit_threshold"] < 255
    np.testing.assert_allclose(maps["screen_m"][mask][ok], screen.T[ok] / 1000, atol=1e-6)
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
    measurement = str(d / "measurement_facet.h5")
    for flag, typed, needle in (
        ("--response", d / "camera_sofast_downsampled.h5", "not an OpenCSP image calibration"),
        ("--response", d / "none.h5", "no such file"),
        ("--display", d / "image_calibration.h5", "DisplayShape"),
    ):
        assert main(["decode", measurement, "--out", str(out), flag, str(typed)]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and needle in err and str(typed) in err, err
        assert "Traceback" not in err
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


def test_the_record_is_applied_as_opencsp_applies_it(sofast_dir) -> None:
    """ImageCalibrationScaling.apply_to_images written out as OpenCSP writes it (scipy's
    interp1d, the mask images scaled to display_values[-1], 0 where white is not above
    black) against glshade's one implementation (Response kind sofast)."""
    from scipy import interpolate

    from glshade.capture.sofast import read_sofast_capture

    m = read_sofast_measurement(sofast_dir / "measurement_facet.h5")
    c = read_sofast_calibration(sofast_dir / "image_calibration.h5")
    cam, disp = c.camera_values, c.display_values
    idxs = np.where(np.diff(cam) <= 0)[0]
    f = interpolate.interp1d(
        np.delete(cam, idxs), np.delete(disp, idxs), bounds_error=False,
        fill_value=(disp[0], disp[-1]),
    )  # fmt: skip
    images = np.moveaxis(m.frames, 0, -1)
    dark, light = f(m.black[..., None]), f(m.white[..., None])
    delta = light - dark
    delta[delta <= 0] = np.nan
    theirs = (f(images) - dark) * (disp[-1].astype(float) / delta)
    theirs[np.isnan(theirs)] = 0
    ours = c.apply(m)
    np.testing.assert_allclose(ours, np.moveaxis(theirs, -1, 0), rtol=1e-12, atol=1e-12)
    capture = read_sofast_capture(sofast_dir / "measurement_facet.h5", c)
    assert capture.response is not None and capture.response.display_max == disp[-1]
    coding = capture.coding
    assert coding.directions == ("v", "u") and coding.periods == m.periods_y
    assert (coding.period_unit, coding.shifts, coding.shift_sign) == ("screen", 4, 1)
    assert coding.origin == ("low", "high") and coding.order == ("direction", "period", "shift")
    assert np.array_equal(capture.black, m.black) and np.array_equal(capture.white, m.white)


def test_the_per_period_rule_keeps_the_edge_pixels_at_sofasts_precision(sofast_dir) -> None:
    """The 7 facet-edge pixels whose finest y fringe is blurred below the threshold: the
    per-period rule keeps them from their own finest phase (coarser periods sound,
    unwrapping margin above 0.4 turn), every pixel of SOFAST's mask within 1e-6 rms."""
    from glshade.capture.decode import DecodeSettings, decode_capture
    from glshade.capture.sofast import read_sofast_capture

    d = sofast_dir
    capture = read_sofast_capture(d / "measurement_facet.h5", d / "image_calibration.h5")
    decoded = decode_capture(capture, settings=DecodeSettings(rule="periods"))
    mask, frac = _expected(sofast_dir)
    assert decoded.valid[mask].all()
    edge = ~decoded.period_valid[1, 0][mask]
    assert edge.sum() == 7 and (decoded.finest_used[1][mask] == 0).all()
    assert decoded.period_valid[1, 1:][:, mask][:, edge].all()
    assert decoded.margin[1][mask][edge].min() > 0.4
    for axis in (0, 1):
        diff = decoded.fraction[..., axis][mask] - frac[axis]
        assert np.sqrt(np.mean(diff**2)) <= 1e-6 and np.abs(diff).max() < 1e-6
