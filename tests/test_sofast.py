from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("h5py")

from glshade.capture.sofast import read_sofast_calibration, read_sofast_measurement


def _data() -> Path:
    here = Path(__file__).resolve().parents[1]
    for cand in (here.parent / "shared" / "sofast", here / "shared" / "sofast"):
        if (cand / "measurement_facet.h5").exists():
            return cand
    pytest.skip("SOFAST data (shared/sofast) absent")


def test_reader_frames_and_masks() -> None:
    m = read_sofast_measurement(_data() / "measurement_facet.h5")
    assert m.frames.shape == (32, 154, 203)
    assert m.black.shape == m.white.shape == (154, 203)
    assert m.shifts == 4
    assert m.periods_x == (0.9, 3.9, 15.9, 63.9)
    assert m.white.mean() > m.black.mean()
    assert abs(m.dist_optic_screen_mm - 10232.0) < 1.0


def test_calibration_reader() -> None:
    c = read_sofast_calibration(_data() / "image_calibration.h5")
    assert c.camera_values.shape == c.display_values.shape == (27,)
    out = c.response(np.array([[0, 128, 255]], dtype=np.uint8))
    assert out.shape == (1, 3) and np.all(np.isfinite(out))


def _expected() -> tuple[np.ndarray, np.ndarray]:
    import h5py

    with h5py.File(_data() / "expected_facet.h5", "r") as h5:
        g = h5["DataSofastCalculation/facet/facet_000"]
        mask = g["CalculationImageProcessingFacet/mask_processed"][()].astype(bool)
        frac = g["CalculationDataGeometryFacet/v_screen_points_fractional_screens"][()]
    return mask, frac


def test_decode_matches_sofast_calibrated_and_raw() -> None:
    from glshade.capture.sofast import decode_sofast

    d = _data()
    m = read_sofast_measurement(d / "measurement_facet.h5")
    c = read_sofast_calibration(d / "image_calibration.h5")
    mask, frac = _expected()
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
