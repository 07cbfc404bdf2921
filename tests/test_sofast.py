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
    out = c.apply(np.array([[0, 128, 255]], dtype=np.uint8))
    assert out.shape == (1, 3) and np.all(np.isfinite(out))
