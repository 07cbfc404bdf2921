"""The sensor's black level: an offset in DN added before the converter clips at 0, kept in
the recorded values, the full well filling the range above it; what glshade subtracts it
from (the validity threshold's base, the noise prediction, the exposure statuses); its
"auto" value and its refusals; and the bias it removes (read noise clipped at 0 in the
fringes' dark troughs)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from glshade.app.cli import main
from glshade.components.registry import registry
from glshade.instruments.pmd.capture import capture
from glshade.instruments.pmd.station import measure_pmd_scene
from glshade.instruments.stripes.single import measure_scene
from glshade.metrics.status import exposure_problem
from glshade.scene import paper_scene

SENSOR = {"full_well_e": 10000.0, "read_noise_e": 5.0, "bit_depth": 12, "seed": 4}


def sensor_scene(**sensor):
    return (
        paper_scene("flat")
        .with_size(8)
        .updated(camera={"exposure": 1.0}, sensor={**SENSOR, **sensor})
    )


def develop(scene, radiance: float, shape=(300, 300)) -> np.ndarray:
    image = np.full(shape, radiance, np.float32)
    return registry().active(scene).sensor.develop(scene, image).astype(np.float64)


def test_the_black_level_is_an_offset_the_full_well_fills_the_range_above():
    """Uniform radiance 0.5 at exposure 1 records ``b + (1 - b) 0.5``, with the variance
    of ``(1 - b)² (0.5 full_well + read²) / full_well²`` plus the quantisation's; radiance
    1 just fills the range (never beyond full scale), 0 reads the black level."""
    scene = sensor_scene(bit_depth=16)
    black = 1024 / 65535  # "auto" at 16 bits: 2^(16 - 6) DN
    assert scene.sensor.black_dn == 1024 and scene.sensor.black_level == black
    image = develop(scene, 0.5)
    assert image.mean() == pytest.approx(black + (1 - black) * 0.5, abs=3e-4)
    variance = (1 - black) ** 2 * (0.5 * 1e4 + 25.0) / 1e8 + 1.0 / (12.0 * 65535.0**2)
    assert image.var() == pytest.approx(variance, rel=0.03)
    assert (develop(scene, 1.5) == 1.0).all()
    # a full well of electrons reaches full scale: half the pixels of radiance 1 clip there
    assert (develop(scene, 1.0) == 1.0).mean() == pytest.approx(0.5, abs=0.02)
    dark = develop(scene, 0.0)
    assert dark.mean() == pytest.approx(black, abs=5e-6)
    assert dark.std() == pytest.approx((1 - black) * 5.0 / 1e4, rel=0.03)
    # "auto" exposure keeps a tenth of the range above the black level as headroom
    auto = develop(scene.updated(camera={"exposure": "auto"}), 0.5)
    assert auto.mean() == pytest.approx(black + (1 - black) * 0.9, abs=3e-4)


def clipped_dark(sigma_dn: float) -> tuple[float, float]:
    """A dark pixel's readings without a black level, from the normal distribution of its
    read noise (``sigma_dn`` DN) clipped at 0 and rounded: the share of exact zeros,
    ``Φ(0.5 / σ)``, and the mean reading (DN), ``Σ_k k P(round = k)``."""

    def cdf(x: float) -> float:
        return 0.5 * (1.0 + math.erf(x / (sigma_dn * math.sqrt(2.0))))

    mean = sum(k * (cdf(k + 0.5) - cdf(k - 0.5)) for k in range(1, int(12 * sigma_dn) + 2))
    return cdf(0.5), mean


def test_without_a_black_level_the_dark_is_clipped_and_biased():
    """Read noise below 0 DN is clipped: at 12 bits and 5 e- of 10 000 (2.05 DN) 60 % of
    a dark pixel's readings are exactly 0 and its mean is biased up by 0.8 DN; the black
    level keeps every reading and reads it on average."""
    sigma_dn = 5.0 / 1e4 * 4095
    zeros, mean_dn = clipped_dark(sigma_dn)
    bare = develop(sensor_scene(black_level_dn=0), 0.0) * 4095
    assert (bare == 0.0).mean() == pytest.approx(zeros, abs=0.005)
    assert bare.mean() == pytest.approx(mean_dn, abs=0.02)
    assert mean_dn == pytest.approx(0.8, abs=0.05)
    offset = develop(sensor_scene(), 0.0) * 4095
    assert (offset == 0.0).sum() == 0
    assert offset.mean() == pytest.approx(64.0, abs=0.02)


@pytest.mark.parametrize(
    ("sensor", "expected_dn"),
    [
        ({"bit_depth": 8}, 4),
        ({"bit_depth": 10}, 16),
        ({"bit_depth": 12}, 64),
        ({"bit_depth": 16}, 1024),
        ({"bit_depth": 12, "full_well_e": 300.0}, math.ceil(6 * 5.0 * 4095 / 300.0)),
        ({"bit_depth": 8, "full_well_e": 100.0, "read_noise_e": 50.0}, 63),  # capped at 1/4
        ({"black_level_dn": 0}, 0),
        ({"black_level_dn": 200}, 200),
    ],
)
def test_the_black_level_in_dn(sensor, expected_dn):
    """ "auto": full scale / 64, or six read-noise σ where that is more, at most a quarter
    of full scale; a number as given."""
    scene = sensor_scene(**sensor)
    assert scene.sensor.black_dn == expected_dn
    assert scene.sensor.black_level == expected_dn / (2**scene.sensor.bit_depth - 1)


def test_no_sensor_has_no_black_level():
    assert paper_scene().sensor.black_dn == 0 and paper_scene().sensor.black_level == 0.0


@pytest.mark.parametrize(
    ("value", "words"),
    [
        ("2000", ["sensor.black_level_dn", "1023", "2000"]),
        ("-1", ["sensor.black_level_dn", "-1"]),
        ("dark", ["sensor.black_level_dn", "dark"]),
    ],
)
def test_a_bad_black_level_is_one_line_and_exit_2(tmp_path, capsys, value, words):
    maps = tmp_path / "maps"
    args = ["measure", "--method", "pmd", "--size", "16", "--full-well", "10000"]
    code = main([*args, "--black-level", value, "--maps", str(maps)])
    err = capsys.readouterr().err.strip()
    assert code == 2 and err.count("\n") == 0, err
    for word in words:
        assert word in err, err
    assert not maps.exists()


# --------------------------------------------------------------------------- what is subtracted
def test_the_threshold_and_the_noise_prediction_leave_the_black_level_out(renderer):
    """The validity threshold's base is the white's response above the black level: the
    same share of full scale the signal fills, ``(1 - b) · 0.9`` under "auto"; the noise
    prediction subtracts it from the mean level, and the measured noise follows it (the
    black level at 1/4 of full scale, where adding it to the photon term would predict
    about 1.5 times the noise)."""
    scene = (
        paper_scene("flat")
        .with_size(64)
        .updated(emitter={"kind": "fringes"}, sensor={**SENSOR, "black_level_dn": 1023})
    )
    black = 1023 / 4095
    shot = capture(renderer, scene)
    assert shot.black_level == black
    assert shot.peak_response == pytest.approx((1 - black) * 0.9, rel=1e-6)
    recorded = shot.recorded()
    assert recorded.min() > 0.5 * black and np.percentile(recorded, 99.9) < 0.97
    result = measure_pmd_scene(renderer, scene)
    assert result.status == "ok"
    assert result.maps.recording.threshold == pytest.approx(0.1 * 0.5 * (1 - black) * 0.9)
    assert result.pmd_noise_mm == pytest.approx(result.pmd_noise_predicted_mm, rel=0.15)


def test_the_exposure_statuses_are_measured_above_the_black_level():
    """A peak signal of 9 % of the range above a black level of 1/4 records 0.32 of full
    scale: underexposed all the same."""
    black = 0.25
    image = np.full((20, 20), black + (1 - black) * 0.09)
    seen = np.ones(image.shape, bool)
    found = exposure_problem(image, seen, black)
    assert found is not None and found.status == "underexposed" and "9.0%" in found.reason
    assert exposure_problem(image, seen) is None  # the black level counted as signal
    assert exposure_problem(np.full((20, 20), 1.0), seen, black).status == "saturated"


def test_the_stripe_instrument_reads_a_sensor_with_a_black_level(renderer):
    """Its binarisation level follows the image's range: the offset changes nothing it
    measures beyond the noise (the noise draws differ with the scene's black level)."""
    scene = paper_scene("flat", 45.0, 4.0, 0.005).with_size(192)
    scene = scene.updated(sensor={"full_well_e": 10000.0})
    noiseless = measure_scene(renderer, scene.updated(sensor={"full_well_e": None}))
    for black in ("auto", 0, 1023):
        measured = measure_scene(renderer, scene.updated(sensor={"black_level_dn": black}))
        assert measured.status == "ok", measured.status_reason
        assert abs(measured.visibility_px - noiseless.visibility_px) <= 1.0
        assert measured.noise_floor_px is not None and measured.noise_floor_px <= 1.0
