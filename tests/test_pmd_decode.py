"""Phase-measuring deflectometry, the station's side: decoding synthetic fringe sequences
whose answer is known by construction, the noise a decoder reaches, unwrapping failures,
and heights integrated from known slopes."""

from __future__ import annotations

import numpy as np
import pytest

from glshade.errors import GlshadeError
from glshade.metrics import pmd

CODING = pmd.FringeCoding(levels=0)  # continuous grey levels, gamma 1


def screen(coding: pmd.FringeCoding, size: int = 4000) -> np.ndarray:
    """A smooth, monotonic map of screen coordinates (mm from the edge) over most of the
    screen: a row of ``size`` pixels."""
    x = np.linspace(0.0, 1.0, size)
    return (0.02 + 0.95 * x + 0.02 * np.sin(3.0 * x)) * coding.screen_extent_mm


def test_noise_free_decoding_recovers_the_map():
    s = screen(CODING)
    decoded = pmd.decode(CODING.sequence(s), CODING)
    assert decoded.valid.all()
    assert np.max(np.abs(decoded.s_mm - s)) < 1e-9
    assert np.allclose(decoded.modulation, CODING.amplitude) and np.allclose(decoded.offset, 0.5)
    # 8-bit screen levels: a phase error of a fraction of a grey level, far below a period
    eight = pmd.FringeCoding(levels=256)
    error = np.abs(pmd.decode(eight.sequence(s), eight).s_mm - s)
    assert 1e-6 < error.max() < 2e-3 * eight.periods_mm[0]


def test_gamma_harmonics_alias_into_three_steps_and_fade_with_more():
    """A screen gamma adds harmonics h of the fringe. N equal steps cancel every harmonic
    but those with h ≡ ±1 (mod N), which alias into the phase: N = 3 aliases the 2nd
    (the strongest), N = 4 the 3rd, N = 8 the 7th, each much weaker than the last."""
    s = screen(CODING)
    errors = {}
    for shifts in (3, 4, 8):
        coding = pmd.FringeCoding(shifts=shifts, gamma=2.2, levels=0)
        errors[shifts] = np.max(np.abs(pmd.decode(coding.sequence(s), coding).s_mm - s))
    finest = CODING.periods_mm[0]
    assert errors[3] > 5 * errors[4] > 0
    assert errors[4] > 20 * errors[8]
    assert errors[3] > 1e-3 * finest and errors[8] < 1e-4 * finest
    # gamma 1 has no harmonics: three steps are exact
    three = pmd.FringeCoding(shifts=3, levels=0)
    assert np.max(np.abs(pmd.decode(three.sequence(s), three).s_mm - s)) < 1e-9


@pytest.mark.parametrize("shifts", [4, 8])
def test_decoded_noise_matches_the_prediction(shifts):
    coding = pmd.FringeCoding(shifts=shifts, levels=0)
    s = screen(coding, 20000)
    clean = coding.sequence(s)
    sigma = 0.01
    spreads = []
    for seed in range(4):
        noise = np.random.default_rng(seed).normal(0.0, sigma, clean.shape)
        decoded = pmd.decode(clean + noise, coding)
        assert pmd.unwrap_failures(decoded.s_mm, s, coding.periods_mm[0]) == 0
        spreads.append(np.std(decoded.s_mm - s))
    predicted = pmd.predicted_noise_mm(coding, sigma, coding.amplitude)
    assert np.mean(spreads) == pytest.approx(predicted, rel=0.15)


def test_unwrapping_fails_where_the_period_ratio_outgrows_the_noise():
    """Neighbour periods 1:64 tolerate a phase noise of about π/64 on the coarser one: at
    an intensity noise that gives a few times that, fringes are mis-counted; at 1:8 they
    are not. The failures are counted against the exact map."""
    s = screen(CODING, 20000)
    sigma = 0.03
    wide = pmd.FringeCoding(periods_mm=(4.0, 256.0, 16384.0), levels=0)
    safe = pmd.FringeCoding(periods_mm=(4.0, 32.0, 256.0, 2048.0), levels=0)
    counts = {}
    for name, coding in (("wide", wide), ("safe", safe)):
        clean = coding.sequence(s)
        noisy = clean + np.random.default_rng(1).normal(0.0, sigma, clean.shape)
        decoded = pmd.decode(noisy, coding)
        counts[name] = pmd.unwrap_failures(decoded.s_mm, s, coding.periods_mm[0])
        wrong = np.abs(decoded.s_mm - s) > 0.5 * coding.periods_mm[0]
        assert counts[name] == int(wrong.sum())
    assert counts["wide"] > 100 and counts["safe"] == 0


def test_pixels_without_modulation_are_not_valid():
    s = screen(CODING, 100)
    frames = CODING.sequence(s)
    frames[:, :, 40:60] = 0.3  # a pixel that sees a grey patch: no fringe at all
    decoded = pmd.decode(frames, CODING)
    assert not decoded.valid[40:60].any() and decoded.valid[:40].all()
    assert np.isnan(decoded.s_mm[40:60]).all()
    # a higher threshold drops dim fringes too
    dim = CODING.sequence(s) * 0.05
    assert not pmd.decode(dim, CODING).valid.any()
    assert pmd.decode(dim, CODING, peak_response=0.05).valid.all()


def test_heights_from_slopes_and_the_dent_they_hold():
    spacing = 0.1
    x = (np.arange(121) - 60) * spacing
    z = (np.arange(101) - 50) * spacing
    xx, zz = np.meshgrid(x, z)
    depth, sigma = 5e-3, 1.5
    gauss = np.exp(-(xx**2 + zz**2) / (2 * sigma**2))
    tilt = 2e-4 * xx - 1e-4 * zz + 0.3
    height = -depth * gauss + tilt
    slope_x = depth * gauss * xx / sigma**2 + 2e-4
    slope_z = depth * gauss * zz / sigma**2 - 1e-4
    outside = xx**2 + zz**2 > (4 * sigma) ** 2
    recovered = pmd.integrate_slopes(slope_x, slope_z, (spacing, spacing), outside=outside)
    expected = pmd.remove_plane(height, outside)
    assert np.nanmax(np.abs(recovered - expected)) < 0.01 * depth
    dent = pmd.dent_from_height(recovered, xx, zz)
    assert dent.depth == pytest.approx(depth, rel=0.02)
    assert dent.sigma_mm == pytest.approx(sigma, rel=0.05)
    assert abs(dent.x0_mm) < 0.05 and abs(dent.z0_mm) < 0.05
    # a hole in the valid region: the rest still integrates, the hole stays NaN
    valid = np.ones_like(outside)
    valid[:10, :10] = False
    holed = pmd.integrate_slopes(slope_x, slope_z, (spacing, spacing), valid, outside)
    assert np.isnan(holed[:10, :10]).all() and np.isfinite(holed[20:, 20:]).all()


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"shifts": 2}, "shifts: must be an integer >= 3, got 2"),
        ({"periods_mm": (2.0, 16.0, 128.0)}, "the coarsest (128 mm) must span the screen's 300"),
        ({"periods_mm": (16.0, 2.0, 1024.0)}, "periods: must grow from the finest"),
        ({"gamma": 0.0}, "gamma: must be a finite number > 0, got 0.0"),
        ({"levels": 1}, "levels: must be 0 (continuous) or at least 2 grey levels, got 1"),
        ({"offset": 0.6, "amplitude": 0.5}, "offset + amplitude: must be at most 1"),
    ],
)
def test_bad_codings_are_one_line(changes, message):
    with pytest.raises(GlshadeError) as info:
        pmd.FringeCoding(**changes)
    assert message in str(info.value) and "\n" not in str(info.value)


def test_decode_refuses_a_sequence_of_another_shape():
    with pytest.raises(GlshadeError, match=r"frames must have shape \(4, 4, \.\.\.\)"):
        pmd.decode(np.zeros((3, 4, 5)), CODING)
