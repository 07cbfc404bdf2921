"""The visibility pipeline on synthetic emitter maps and images (no GL), and against the
flat closed form (GL). The contour rules themselves are tested in test_contours.py."""

from __future__ import annotations

import math

import numpy as np
import pytest

from glshade.errors import GlshadeError
from glshade.metrics import contours as ct
from glshade.metrics import visibility as V
from glshade.scene import Emitter, Scene, paper_scene

H, W = 240, 320
MM_PER_ROW = 0.1  # the synthetic emitter map: v grows 0.1 mm per row
EMITTER = Emitter(period=2.0)  # 20 px per period
PERIOD_PX = EMITTER.period / MM_PER_ROW


def emitter_maps(bump_mm: float, width_px: float = 12.0, tilt_mm_per_col: float = 0.0):
    """v0: stripes of constant v (horizontal, or tilted); v1 = v0 + a Gaussian bump
    centred in the image: contours there move by bump_mm / MM_PER_ROW rows."""
    r, c = np.mgrid[0:H, 0:W].astype(np.float64)
    v0 = (r - H / 2) * MM_PER_ROW + tilt_mm_per_col * (c - W / 2)
    bump = bump_mm * np.exp(-((r - H / 2) ** 2 + (c - W / 2) ** 2) / (2 * width_px**2))
    return v0, v0 + bump


def images(v0, v1):
    return (lambda p: V.stripe_radiance(v0, EMITTER, p)), (
        lambda p: V.stripe_radiance(v1, EMITTER, p)
    )


@pytest.mark.parametrize("shift_px", [2.0, 5.0, 8.5])
def test_paper_metric_recovers_an_imposed_displacement(shift_px):
    v0, v1 = emitter_maps(shift_px * MM_PER_ROW)
    result = V.image_visibility(*images(v0, v1), EMITTER.period)
    assert abs(result.visibility_px - shift_px) <= 1.0
    assert result.offset_px == (0, 0) and result.unpaired == 0 and result.islands == 0
    assert len(result.per_phase) == 8  # 0, 0.25, …, 1.75 mm
    # and no displacement, no visibility
    assert V.image_visibility(*images(v0, v0), EMITTER.period).visibility_px == 0.0
    # the pipeline from the emitter maps gives the same paper metric as from the images
    assert V.Baseline(v0, EMITTER).measure(v1).visibility_px == result.visibility_px


@pytest.mark.parametrize("shift_px", [2.0, 5.0, 8.5])
def test_continuous_numbers_are_exact_on_an_imposed_displacement(shift_px):
    v0, v1 = emitter_maps(shift_px * MM_PER_ROW)
    result = V.Baseline(v0, EMITTER).measure(v1)
    # the largest |r - r0| sits at the bump's centre: exactly the imposed shift, and
    # where nothing folds the continuous limit of the paper's metric is that displacement
    assert result.deflection_px == pytest.approx(shift_px, abs=0.02)
    assert result.visibility_continuous_px == result.deflection_px
    assert not result.folded and result.limit.window is None
    kept = V.kept_columns(W, 0.5)
    assert np.isnan(result.displacement_px[:, : kept.start]).all()


def test_identity_wins_over_nearness():
    """A displacement of 0.8 period: under nearest-neighbour matching each displaced
    contour would sit 0.2 period from the *next* contour; identity must measure 0.8."""
    shift_px = 0.8 * PERIOD_PX  # 16 px
    v0, v1 = emitter_maps(shift_px * MM_PER_ROW, width_px=25.0)
    normal = V.binarize(V.stripe_radiance(v0, EMITTER, 0.0), V.MetricSettings())
    defect = V.binarize(V.stripe_radiance(v1, EMITTER, 0.0), V.MetricSettings())
    columns = V.kept_columns(W, 0.5)
    # the nearest-neighbour answer, for contrast: distance of each defect edge pixel to
    # the nearest normal edge pixel in its column
    a, b = ct.contour_image(normal[:, columns]) > 0, ct.contour_image(defect[:, columns]) > 0
    nearest = max(
        np.abs(np.nonzero(a[:, j])[0][:, None] - np.nonzero(b[:, j])[0][None, :]).min(axis=0).max()
        for j in range(a.shape[1])
    )
    assert nearest <= 0.3 * PERIOD_PX
    result = V.image_visibility(*images(v0, v1), EMITTER.period)
    assert abs(result.visibility_px - shift_px) <= 1.0, (result.visibility_px, nearest)


def test_registration_of_a_shifted_pair():
    """The defect image moved by whole pixels: registration finds the move, reports it,
    and the visibility is that of the unmoved pair."""
    v0, v1 = emitter_maps(4 * MM_PER_ROW, tilt_mm_per_col=0.03)
    settings = V.MetricSettings()
    reference = V.image_visibility(*images(v0, v1), EMITTER.period, settings)
    moved = np.full_like(v1, np.nan)
    moved[3:, :-2] = v1[:-3, 2:]  # content moves 3 rows down and 2 columns left
    result = V.image_visibility(*images(v0, moved), EMITTER.period, settings)
    assert result.offset_px == (2, -3)
    assert result.visibility_px == reference.visibility_px


def test_fold_is_reported_not_hidden():
    """A bump steep enough to fold the map: v1 is not monotonic along the columns, islands
    appear, and what the contours show (the paper's metric and its limit) stays far below
    how far the rays move."""
    v0, v1 = emitter_maps(3.0, width_px=4.0)  # 30 px of shift over a 4 px wide bump
    result = V.Baseline(v0, EMITTER).measure(v1)
    assert result.folded and result.islands > 0
    assert result.deflection_px == pytest.approx(30.0, abs=0.5)
    assert (
        result.visibility_continuous_px < 0.6 * result.deflection_px
    )  # islands and a capped contour: 15.8 of 30 px
    assert abs(result.visibility_px - result.visibility_continuous_px) <= 1.5
    paper = V.image_visibility(*images(v0, v1), EMITTER.period)
    assert paper.islands > 0 and paper.visibility_px == result.visibility_px


def test_phases_and_settings_validation():
    settings = V.MetricSettings(step_mm=0.25)
    np.testing.assert_allclose(settings.phases(2.0), np.arange(8) * 0.25)
    assert len(settings.phases(10.0)) == 40
    with pytest.raises(GlshadeError, match="at most one stripe period"):
        V.MetricSettings(step_mm=3.0).phases(2.0)
    for bad in (
        dict(threshold=1.0),
        dict(keep_fraction=0.0),
        dict(step_mm=-1.0),
        dict(min_period_px=-1),
        dict(max_offset_px=-1),
        dict(limit_upsample=0),
        dict(limit_phases=2),
    ):
        with pytest.raises(GlshadeError):
            V.MetricSettings(**bad)


def test_binarising_from_v_equals_thresholding_the_radiance():
    v = np.linspace(-30.0, 30.0, 200001)
    half = V.stripe_half_width(EMITTER, 0.5)
    for phase in (0.0, 0.25, 1.3):
        exact = V.stripe_radiance(v, EMITTER, phase) > 0.5
        fast = V.binarize_v(v, EMITTER, phase, half)
        assert (exact != fast).sum() <= 2 * 30  # only at the threshold's float rounding
    # L(w*) is the threshold (neighbouring stripes add 0.002 there, so w* sits 1.4 µm
    # beyond the quarter period that one stripe's FWHM alone would give)
    assert float(V.stripe_radiance(np.array([half]), EMITTER, 0.0)[0]) == pytest.approx(
        0.5, abs=1e-6
    )
    assert half == pytest.approx(EMITTER.period / 4, rel=0.01)


def test_otsu_threshold_option():
    v0, v1 = emitter_maps(0.5)
    result = V.image_visibility(*images(v0, v1), EMITTER.period, V.MetricSettings(otsu=True))
    assert abs(result.visibility_px - 5.0) <= 1.0


def test_overlay_colours_of_fig9():
    v0, v1 = emitter_maps(0.5)
    normal = V.stripe_radiance(v0, EMITTER, 0.0) > 0.5
    defect = V.stripe_radiance(v1, EMITTER, 0.0) > 0.5
    rgb = ct.overlay_rgb(ct.find_stripes(normal), ct.find_stripes(defect))
    magenta = (rgb[..., 0] == 255) & (rgb[..., 2] == 255)
    red = (rgb[..., 0] == 255) & (rgb[..., 2] == 0)
    blue = (rgb[..., 0] == 0) & (rgb[..., 2] == 255)
    assert magenta.sum() > red.sum() > 0 and blue.sum() > 0
    assert (rgb[..., 1] == 0).all()
    # away from the bump everything overlaps
    assert not (red[:40] | blue[:40]).any()


def test_resolved_mask_leaves_out_aliased_stripes():
    r = np.arange(100, dtype=float)[:, None] * np.ones((1, 10))
    v = np.where(r < 50, r * 1.0, 50 + (r - 50) * 0.1)  # 2 px per period above, 20 below
    mask = V.resolved_mask(v, 2.0, 4.0)
    assert not mask[10:45].any() and mask[55:95].all()


def test_deflection_flat_closed_form(renderer):
    """SPEC §6: on a flat mirror, small slopes, the deflection tends to
    2 (dmax/σ) e^(-1/2) De f / ((Dc + De) pitch) ≈ 18.0 px for σ² 1, dmax 5 µm, at every θ;
    where the fold does not cap it (θ 85, 45) the continuous limit is that deflection."""
    expected = 2 * (0.005 / 1.0) * math.exp(-0.5) * 256.0 * 25.0 / ((175.6 + 256.0) * 0.005)
    assert expected == pytest.approx(18.0, abs=0.02)
    for theta in (85.0, 45.0, 15.0):
        scene = paper_scene("flat", theta, 1.0, 0.005)
        v0 = renderer.render(scene.without_defect(), ("uv",)).uv[..., 1]
        v1 = renderer.render(scene, ("uv",)).uv[..., 1]
        result = V.Baseline(v0, scene.emitter).measure(v1)
        assert result.deflection_px == pytest.approx(expected, rel=0.02), theta
        if theta >= 45.0:
            assert result.visibility_continuous_px == pytest.approx(
                result.deflection_px, rel=0.01
            ), theta
        else:  # at 15° the fold caps it (physics.md §3: 12.3 px)
            assert result.visibility_continuous_px == pytest.approx(12.3, rel=0.02)


@pytest.mark.parametrize("ratio", [0.05, 0.1, 0.2, 0.2123, 0.3, 0.5, 1.0, 3.0])
def test_the_stripes_left_out_of_the_radiance_change_no_bit(ratio):
    """The radiance sums only the stripes that can change its float64 sum: against the sum
    over every stripe within 10 σ, bit for bit, stripe edges and centres included."""
    from glshade.components.emitter.stripes.table import silent_beyond

    period = 2.0
    sigma = ratio * period
    rng = np.random.default_rng(7)
    v = np.concatenate([rng.uniform(-300, 300, 50_000), np.arange(-40, 41) * period / 2, [np.nan]])
    reach = math.ceil(10.0 * sigma / period) + 1
    w = (v - 0.3) / period
    w -= np.round(w)
    every, scale = np.zeros(w.shape), period / sigma
    for k in range(-reach, reach + 1):
        every += np.exp(-0.5 * ((w - k) * scale) ** 2)
    scene = Scene().updated(emitter={"period": period, "stripe_sigma": sigma})
    pattern = scene.active.emitter.pattern(scene)
    np.testing.assert_array_equal(pattern.radiance(v, 0.3), every)
    # narrow stripes (the paper's: σ = 0.21 period) leave the far ones out
    assert silent_beyond(reach, scale) < reach if ratio <= 0.25 else True
