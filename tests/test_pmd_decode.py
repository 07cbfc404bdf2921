"""Phase-measuring deflectometry, the station's side: decoding synthetic fringe sequences
whose answer is known by construction, the noise a decoder reaches, unwrapping failures,
and heights integrated from known slopes."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import label

from glshade.components.emitter.fringes.codec import displayed_fringe
from glshade.components.emitter.fringes.screen import ScreenResponse
from glshade.errors import GlshadeError
from glshade.instruments.pmd import decode as pmd


def one_direction(**values) -> pmd.FringeCodec:
    """A codec of the ``v`` direction alone (what one decode takes), default otherwise."""
    return pmd.FringeCodec(directions=("v",), **values)


CODING = one_direction(levels=0)  # continuous grey levels, gamma 1


def screen(coding: pmd.FringeCodec, size: int = 4000) -> np.ndarray:
    """A smooth, monotonic map of screen coordinates (mm from the edge) over most of the
    screen: a row of ``size`` pixels."""
    x = np.linspace(0.0, 1.0, size)
    return (0.02 + 0.95 * x + 0.02 * np.sin(3.0 * x)) * coding.extent_mm()


def test_noise_free_decoding_recovers_the_map():
    s = screen(CODING)
    decoded = pmd.decode(CODING.sequence(s), CODING)
    assert decoded.valid.all()
    assert np.max(np.abs(decoded.s_mm - s)) < 1e-9
    assert np.allclose(decoded.modulation, CODING.amplitude) and np.allclose(decoded.offset, 0.5)
    assert np.all((decoded.wrapped >= 0) & (decoded.wrapped < 2 * np.pi))


def test_eight_bit_levels_stay_within_their_bound():
    """Rounding to ``levels`` grey levels errs by at most half a level ``q / 2`` (``q = 1 /
    (levels - 1)``) per frame; the errors' phasor ``(2/N) Σ e_n exp(iδ_n)`` is then at most
    ``q``, so the phase errs by at most ``asin(q / B)`` and the coordinate by ``p_1 / 2π``
    times that."""
    s = screen(CODING)
    eight = one_direction(levels=256)
    error = np.abs(pmd.decode(eight.sequence(s), eight).s_mm - s)
    bound = eight.periods_mm[0] / (2 * np.pi) * np.arcsin((1 / 255) / eight.amplitude)
    assert 1e-6 < error.max() < bound
    assert error.max() > 0.1 * bound  # a real effect, not a vanishing one


def test_an_image_of_screen_points_decodes_pixel_for_pixel():
    """A (K, N, H, W) sequence of a smooth 2-D map (what a camera sees)."""
    rows, cols = np.mgrid[0:60, 0:80]
    s = 5.0 + 2.9 * cols + 0.8 * rows + 3.0 * np.sin(cols / 7.0) * np.cos(rows / 5.0)
    frames = CODING.sequence(s)
    assert frames.shape == (4, 4, 60, 80)
    decoded = pmd.decode(frames, CODING)
    assert decoded.modulation.shape == decoded.wrapped.shape == decoded.offset.shape
    assert decoded.modulation.shape == (4, 60, 80) and decoded.valid.shape == (60, 80)
    assert np.max(np.abs(decoded.s_mm - s)) < 1e-9
    # the wrapped phase of each period is the exact one
    for k, period in enumerate(CODING.periods_mm):
        exact = np.mod(2 * np.pi * s / period, 2 * np.pi)
        gap = np.angle(np.exp(1j * (decoded.wrapped[k] - exact)))
        assert np.max(np.abs(gap)) < 1e-9


def test_the_displayed_radiance_is_the_formula():
    s = np.linspace(0.0, 300.0, 1001)
    # frame (k = 1, n = 1): the 16 mm fringe shifted by a quarter turn
    shown = one_direction(offset=0.5, amplitude=0.4, levels=0).radiance(s, 1, 1)
    assert shown.dtype == np.float64
    assert np.allclose(shown, 0.5 + 0.4 * np.cos(2 * np.pi * s / 16.0 - np.pi / 2), atol=1e-15)
    levels = one_direction(levels=4, gamma=2.0).radiance(s, 1, 0)
    # the fraction of the period, then halves rounded up (s = 84 mm is one: c = 0.5)
    x = s / 16.0 - np.floor(s / 16.0)
    commanded = np.floor((0.5 + 0.5 * np.cos(2 * np.pi * x)) * 3 + 0.5) / 3
    assert np.allclose(levels, commanded**2, atol=1e-15)
    assert set(np.round(levels * 9).astype(int)) <= {0, 1, 4, 9}  # (j/3)² only
    # every argument broadcasts: a column of shifts against a row of coordinates
    steps = CODING.shift_rad(np.arange(4))[:, None]
    grid = displayed_fringe(ScreenResponse(), s[None, :], 16.0, steps, 0.5, 0.5)
    assert grid.shape == (4, 1001) and np.allclose(grid[2], 0.5 - 0.5 * np.cos(2 * np.pi * s / 16))
    assert np.isnan(
        displayed_fringe(ScreenResponse(), np.array([np.nan]), 2.0, 0.0, 0.5, 0.5)
    ).all()
    # the coding's frames are this formula with its values, the screen's frames too
    coding = one_direction(shifts=5, gamma=1.8, levels=64)
    assert coding.shift_rad(2) == pytest.approx(4 * np.pi / 5)
    expected = displayed_fringe(coding.screen(), s, 128.0, 4 * np.pi / 5, 0.5, 0.5)
    assert np.array_equal(coding.radiance(s, 2, 2), expected)
    assert np.array_equal(coding.sequence(s)[2, 2], expected)
    assert np.array_equal(coding.frame_radiance(coding.frame("v", 2, 2), s), expected)


def test_the_phase_is_reduced_to_one_period_first():
    """The fraction of the period is reduced to [0, 1) before the cosine, as the shader
    does: against the cosine of the whole phase the continuous fringe differs by float64
    rounding only, and ``s`` one period on gives the same fraction's fringe."""
    s = np.linspace(0.0, 300.0, 200001)
    continuous = CODING.radiance(s, 0, 1)
    whole = 0.5 + 0.5 * np.cos(2 * np.pi * s / 2.0 - np.pi / 2)
    assert 0.0 < np.abs(continuous - whole).max() < 1e-12
    x = s / 2.0 - np.floor(s / 2.0)
    np.testing.assert_array_equal(continuous, 0.5 + 0.5 * np.cos(2 * np.pi * x - np.pi / 2))


def _fourier(gamma: float, offset: float, amplitude: float, count: int) -> np.ndarray:
    """The cosine coefficients b_h of ``(offset + amplitude cos θ) ** gamma``."""
    theta = np.linspace(0.0, 2 * np.pi, 4096, endpoint=False)
    signal = (offset + amplitude * np.cos(theta)) ** gamma
    return (np.fft.rfft(signal).real * 2 / len(theta))[:count]


def test_gamma_harmonics_alias_into_three_steps_and_fade_with_more():
    """A screen gamma turns the fringe into ``Σ_h b_h cos(h θ)``. N equal steps cancel
    every harmonic but those with h ≡ ±1 (mod N): harmonics 2 … N-2 cancel, so three
    steps alias the 2nd harmonic (the strongest), four the 3rd, eight the 7th. To first
    order the phasor becomes ``e^{iθ} (b_1 + b_{N+1} e^{iNθ} + b_{N-1} e^{-iNθ})``: a
    phase error oscillating at N times the fringe with amplitude ``|b_{N+1} - b_{N-1}| /
    b_1``, predicted here from the Fourier coefficients of ``(0.5 + 0.5 cos θ)^2.2`` and
    measured by decoding."""
    s = screen(CODING)
    b = _fourier(2.2, 0.5, 0.5, 12)
    finest = CODING.periods_mm[0]
    errors = {}
    for shifts in (3, 4, 8):
        coding = one_direction(shifts=shifts, gamma=2.2, levels=0)
        decoded = pmd.decode(coding.sequence(s), coding)
        phase_error = np.max(np.abs(decoded.s_mm - s)) * 2 * np.pi / finest
        predicted = abs(b[shifts + 1] - b[shifts - 1]) / b[1]
        assert phase_error == pytest.approx(predicted, rel=0.05)
        errors[shifts] = phase_error
    # about 0.28 rad, 0.011 rad, 4e-5 rad
    assert errors[3] > 20 * errors[4] > 0
    assert errors[4] > 200 * errors[8]
    assert errors[3] > 0.2 and errors[8] < 1e-4
    # gamma 1 has no harmonics: three steps are exact
    three = one_direction(shifts=3, levels=0)
    assert np.max(np.abs(pmd.decode(three.sequence(s), three).s_mm - s)) < 1e-9


@pytest.mark.parametrize("shifts", [3, 4, 8])
def test_decoded_noise_matches_the_prediction(shifts):
    """Intensity noise σ_I on each frame gives the phase a noise ``sqrt(2/N) σ_I / B``;
    the decoded coordinate keeps the finest period's, ``p_1 / 2π`` times that."""
    coding = one_direction(shifts=shifts, levels=0)
    s = screen(coding, 20000)
    clean = coding.sequence(s)
    sigma = 0.01
    predicted = pmd.predicted_noise_mm(coding, sigma, coding.amplitude)
    assert predicted == pytest.approx(2.0 / (2 * np.pi) * np.sqrt(2 / shifts) * 0.02)
    spreads = []
    for seed in range(4):
        noise = np.random.default_rng(seed).normal(0.0, sigma, clean.shape)
        decoded = pmd.decode(clean + noise, coding)
        assert pmd.unwrap_failures(decoded.s_mm, s, coding.periods_mm[0]) == 0
        spread = np.std(decoded.s_mm - s)
        assert spread == pytest.approx(predicted, rel=0.15)
        spreads.append(spread)
    assert np.mean(spreads) == pytest.approx(predicted, rel=0.05)


def test_noise_at_the_screen_edge_does_not_wrap_round_the_coarsest_period():
    """At ``s`` just above 0 the coarsest phase's noise puts half the pixels just below
    2π, i.e. ``s_K`` near ``p_K`` (1024 mm), far past the 300 mm screen: they are read as
    just below 0, and decode right. A pixel at the far edge is left alone."""
    sigma = 0.01
    for edge in (0.05, CODING.extent_mm() - 0.05):
        s = np.full(20000, edge)
        noisy = CODING.sequence(s) + np.random.default_rng(3).normal(0.0, sigma, (4, 4, 20000))
        decoded = pmd.decode(noisy, CODING)
        assert decoded.valid.all()
        assert pmd.unwrap_failures(decoded.s_mm, s, CODING.periods_mm[0]) == 0
        assert np.max(np.abs(decoded.s_mm - edge)) < 0.1


def test_unwrapping_fails_where_the_period_ratio_outgrows_the_noise():
    """Neighbour periods 1:64 tolerate a phase noise of about π/64 on the coarser one: at
    an intensity noise that gives a few times that, fringes are mis-counted; at 1:8 they
    are not. The failures are counted against the exact map."""
    s = screen(CODING, 20000)
    sigma = 0.03
    wide = one_direction(periods_mm=(4.0, 256.0, 16384.0), levels=0)
    safe = one_direction(periods_mm=(4.0, 32.0, 256.0, 2048.0), levels=0)
    counts = {}
    for name, coding in (("wide", wide), ("safe", safe)):
        clean = coding.sequence(s)
        noisy = clean + np.random.default_rng(1).normal(0.0, sigma, clean.shape)
        decoded = pmd.decode(noisy, coding)
        counts[name] = pmd.unwrap_failures(decoded.s_mm, s, coding.periods_mm[0])
        wrong = np.abs(decoded.s_mm - s) > 0.5 * coding.periods_mm[0]
        assert counts[name] == int(wrong.sum())
    assert counts["wide"] > 100 and counts["safe"] == 0


def test_unwrapping_failures_are_counted_pixel_for_pixel():
    """Failures placed by construction: 37 pixels whose 16 mm frames show the fringe of
    ``s + 9 mm`` (over half that period: the wrong 2 mm fringe is picked), 50 whose 16 mm
    frames show ``s + 0.5 mm`` (a quarter of a 2 mm fringe: still the right one) and 20
    whose frames carry no fringe (not valid, so not counted however far off)."""
    s = screen(CODING, 1000)
    frames = CODING.sequence(s)
    rng = np.random.default_rng(7)
    chosen = rng.permutation(1000)
    wrong, slight, dark = chosen[:37], chosen[37:87], chosen[87:107]
    for n in range(CODING.shifts):
        frames[1, n, wrong] = CODING.radiance(s[wrong] + 9.0, 1, n)
        frames[1, n, slight] = CODING.radiance(s[slight] + 0.5, 1, n)
    frames[:, :, dark] = 0.5
    decoded = pmd.decode(frames, CODING)
    assert pmd.unwrap_failures(decoded.s_mm, s, CODING.periods_mm[0]) == 37
    assert np.all(np.abs(decoded.s_mm[wrong] - s[wrong]) > 5.0)
    assert (
        np.max(
            np.abs(np.delete(decoded.s_mm, np.r_[wrong, dark]) - np.delete(s, np.r_[wrong, dark]))
        )
        < 1e-9
    )
    # a pixel without an exact value (it misses the screen) is not counted either
    exact = s.copy()
    exact[wrong[:7]] = np.nan
    assert pmd.unwrap_failures(decoded.s_mm, exact, CODING.periods_mm[0]) == 30


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
    # an explicit threshold: B = 0.025 passes 0.02 and fails 0.03
    assert pmd.decode(dim, CODING, min_modulation=0.02).valid.all()
    assert not pmd.decode(dim, CODING, min_modulation=0.03).valid.any()
    # one weak period is enough to drop a pixel
    one_weak = CODING.sequence(s)
    one_weak[2, :, 10] = 0.5 + 0.01 * (one_weak[2, :, 10] - 0.5)
    assert not pmd.decode(one_weak, CODING).valid[10]
    assert pmd.decode(one_weak, CODING).valid[np.arange(100) != 10].all()


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
    # Frankot-Chellappa on the same rectangle agrees
    fourier = pmd.integrate_slopes(
        slope_x, slope_z, spacing, outside=outside, method="frankot-chellappa"
    )
    assert np.max(np.abs(fourier - expected)) < 0.01 * depth
    assert pmd.dent_from_height(fourier, xx, zz).depth == pytest.approx(depth, rel=0.02)
    # a hole in the valid region: the rest still integrates, the hole stays NaN
    valid = np.ones_like(outside)
    valid[:10, :10] = False
    holed = pmd.integrate_slopes(slope_x, slope_z, (spacing, spacing), valid, outside)
    assert np.isnan(holed[:10, :10]).all() and np.isfinite(holed[20:, 20:]).all()
    assert np.nanmax(np.abs(holed - expected)) < 0.01 * depth
    with pytest.raises(GlshadeError, match="frankot-chellappa needs every pixel valid, 100 of"):
        pmd.integrate_slopes(slope_x, slope_z, spacing, valid, method="frankot-chellappa")


def test_heights_over_two_separate_regions_and_unequal_spacings():
    """A valid region cut in two by a column of invalid pixels: each half's offset is free,
    so the tilt is fitted in common and each half gets its own offset. The right half is a
    pure tilt and comes back flat; the left one holds the dent. Spacings 0.1 mm along x and
    0.15 mm along z."""
    dx, dz = 0.1, 0.15
    x = (np.arange(161) - 50) * dx
    z = (np.arange(81) - 40) * dz
    xx, zz = np.meshgrid(x, z)
    depth, sigma = 4e-3, 1.0
    gauss = np.exp(-(xx**2 + zz**2) / (2 * sigma**2))
    slope_x = depth * gauss * xx / sigma**2 + 3e-4
    slope_z = depth * gauss * zz / sigma**2 + 2e-4
    valid = np.ones(xx.shape, bool)
    valid[:, 100:103] = False
    outside = xx**2 + zz**2 > (4 * sigma) ** 2
    height = pmd.integrate_slopes(slope_x, slope_z, (dx, dz), valid, outside)
    assert np.isnan(height[:, 100:103]).all() and np.isfinite(height[valid]).all()
    assert np.max(np.abs(height[:, 103:])) < 1e-3 * depth  # the tilt is gone, no step
    assert np.max(np.abs(height[:, :100] + depth * gauss[:, :100])) < 0.02 * depth
    dent = pmd.dent_from_height(height[:, :100], xx[:, :100], zz[:, :100])
    assert dent.depth == pytest.approx(depth, rel=0.02)
    assert dent.sigma_mm == pytest.approx(sigma, rel=0.05)
    # a step between the halves: one plane cannot take it out, an offset per half can
    stepped = height + 0.1 * (xx > 5.0)
    assert np.nanmax(np.abs(pmd.remove_plane(stepped, outside) - height)) > 0.01
    halves = label(valid)[0]
    assert np.nanmax(np.abs(pmd.remove_plane(stepped, outside, halves) - height)) < 1e-12


def _mirror(direction: np.ndarray, normal: np.ndarray) -> np.ndarray:
    return direction - 2 * np.sum(direction * normal, axis=-1, keepdims=True) * normal


def _tilted(slope_x, slope_z) -> np.ndarray:
    """The unit normal of the surface ``y = slope_x x + slope_z z``."""
    n = np.stack(np.broadcast_arrays(-slope_x, 1.0, -slope_z), axis=-1).astype(float)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def test_normals_of_a_flat_mirror_and_of_a_known_tilt():
    """A screen point where the camera's ray, reflected at P by a mirror of normal n,
    lands: the measured normal is n. On the flat nominal mirror (+y) the slope deviation is
    0; on a mirror tilted to slopes (3e-3, -1e-3) it is exactly those slopes."""
    rng = np.random.default_rng(0)
    points = np.column_stack([rng.uniform(-20, 20, 50), np.zeros(50), rng.uniform(-20, 20, 50)])
    camera = np.array([0.0, 400.0, -300.0])
    up = np.array([0.0, 1.0, 0.0])
    for slopes in ((0.0, 0.0), (3e-3, -1e-3), (0.2, 0.1)):
        normal = _tilted(*slopes)
        seen = _mirror(points - camera, normal)  # the reflected ray's direction
        screen_points = points + 700.0 * seen / np.linalg.norm(seen, axis=-1, keepdims=True)
        measured = pmd.normals_from_points(points, camera, screen_points)
        assert np.allclose(np.linalg.norm(measured, axis=-1), 1.0, atol=1e-15)
        assert np.allclose(measured, normal, atol=1e-12)
        gx, gz = pmd.slope_deviation(measured, up)
        assert np.allclose(gx, slopes[0], atol=1e-12) and np.allclose(gz, slopes[1], atol=1e-12)
    # relative to a tilted nominal normal: only the difference counts
    gx, gz = pmd.slope_deviation(_tilted(0.05, 0.02), _tilted(0.04, 0.03))
    assert gx == pytest.approx(0.01, abs=1e-14) and gz == pytest.approx(-0.01, abs=1e-14)
    # a small tilt by an angle α about z: slope tan α ≈ α rad
    alpha = 50e-6
    gx, gz = pmd.slope_deviation(np.array([-np.sin(alpha), np.cos(alpha), 0.0]), up)
    assert gx == pytest.approx(alpha, rel=1e-8) and gz == 0.0


def test_a_dent_seen_in_reflection_comes_back_from_its_screen_points():
    """The whole chain on a flat part with a Gaussian dent: each grid point reflects the
    camera's ray to a screen point with the dented normal; from those screen points the
    measured normals, their slopes against +y, the integrated heights and the fitted dent
    give back the dent's depth and σ."""
    spacing = 0.2
    x = (np.arange(81) - 40) * spacing
    xx, zz = np.meshgrid(x, x)
    depth, sigma = 2e-3, 1.2
    gauss = np.exp(-(xx**2 + zz**2) / (2 * sigma**2))
    normal = _tilted(depth * gauss * xx / sigma**2, depth * gauss * zz / sigma**2)
    points = np.stack([xx, np.zeros_like(xx), zz], axis=-1)
    camera = np.array([0.0, 300.0, -200.0])
    seen = _mirror(points - camera, normal)
    screen_points = points + 500.0 * seen / np.linalg.norm(seen, axis=-1, keepdims=True)
    measured = pmd.normals_from_points(points, camera, screen_points)
    gx, gz = pmd.slope_deviation(measured, np.array([0.0, 1.0, 0.0]))
    outside = xx**2 + zz**2 > (4 * sigma) ** 2
    height = pmd.integrate_slopes(gx, gz, spacing, outside=outside)
    assert np.nanmax(np.abs(height - pmd.remove_plane(-depth * gauss, outside))) < 0.02 * depth
    dent = pmd.dent_from_height(height, xx, zz)
    assert dent.depth == pytest.approx(depth, rel=0.02)
    assert dent.sigma_mm == pytest.approx(sigma, rel=0.05)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"shifts": 2}, "emitter.shifts: must be an integer in [3, 1024], got 2"),
        (
            {"periods_mm": (2.0, 16.0, 128.0)},
            "emitter.periods: must be a coarsest period of at least the screen's extent "
            "along 'v', 2 half_size = 300 mm",
        ),
        ({"periods_mm": (16.0, 2.0, 1024.0)}, "increasing from the finest, got [16.0, 2.0"),
        ({"gamma": 0.0}, "emitter.gamma: must be a finite number > 0, got 0.0"),
        ({"levels": 1}, "emitter.levels: must be 0 (continuous) or at least 2 grey levels"),
        ({"offset": 0.6, "amplitude": 0.5}, "emitter.offset: must be offset + amplitude <= 1"),
    ],
)
def test_bad_codings_are_one_line(changes, message):
    with pytest.raises(GlshadeError) as info:
        one_direction(**changes)
    assert message in str(info.value) and "\n" not in str(info.value)


def test_decode_refuses_a_sequence_of_another_shape():
    with pytest.raises(GlshadeError, match=r"frames must have shape \(4, 4, \.\.\.\)"):
        pmd.decode(np.zeros((3, 4, 5)), CODING)
