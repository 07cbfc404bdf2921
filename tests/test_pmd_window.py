"""A dent's sequence traced over its trace region once its geometry's defect-free one
exists: on every case of the paper's study under phase measuring, the numbers are those of
the dent's sequence traced whole, and outside the region the dent's exact screen points
are the defect-free scene's (what the region takes from it)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from glshade.instruments.pmd.baseline import pmd_baseline
from glshade.instruments.pmd.model import station_model
from glshade.instruments.pmd.shots import shoot
from glshade.instruments.pmd.station import measure_pmd_scene, summary, trace_region
from glshade.study.plan import StudyPlan
from glshade.study.pmd_plan import PmdStudyPlan

SIZE = 64
PLAN = PmdStudyPlan(StudyPlan(size=SIZE))


def same(a: object, b: object) -> bool:
    if isinstance(a, float) and isinstance(b, float):
        return (math.isnan(a) and math.isnan(b)) or a == b
    return a == b


@pytest.mark.parametrize("surface", PLAN.surfaces)
def test_the_region_gives_the_whole_frames_numbers_on_every_study_case(renderer, surface):
    traced = 0
    for theta in PLAN.thetas:
        cases = [c for c in PLAN.cases() if c[0] == surface and c[1] == theta]
        first = PLAN.scene(*cases[0])
        baseline = pmd_baseline(renderer, station_model(first), PLAN.settings)
        for case in cases:
            scene = PLAN.scene(*case)
            box = trace_region(scene, PLAN.settings)
            assert box is not None  # a pinhole: the region can be trusted
            windowed = measure_pmd_scene(renderer, scene, PLAN.settings, baseline)
            whole = measure_pmd_scene(renderer, scene, PLAN.settings, baseline, whole_frame=True)
            mine, theirs = summary(windowed), summary(whole)
            assert all(same(mine[k], theirs[k]) for k in mine), (case, mine, theirs)
            # the exact points the dent's own trace gives outside the region: the
            # defect-free scene's, to far below a millionth of a mm or of the dent's move
            own = shoot(
                renderer,
                scene,
                station_model(scene).coding,
                PLAN.settings,
                peak=baseline.capture.peak_response,
            )
            outside = np.ones(own.uv.shape[:2], bool)
            outside[box.slices] = False
            assert np.array_equal(
                np.isfinite(own.uv[outside]), np.isfinite(baseline.capture.uv[outside])
            )
            moved = np.abs(own.uv - baseline.capture.uv)[outside]
            moved = moved[np.isfinite(moved)]
            largest = windowed.pmd_shift_exact_mm
            limit = max(1e-6, 1e-4 * largest) if math.isfinite(largest) else 1e-6
            assert not moved.size or moved.max() <= limit, (case, moved.max())
            traced += box.rows * box.cols < SIZE * SIZE
    assert traced  # some regions are smaller than the image


def test_a_dent_reads_the_same_from_any_dents_defect_free_analysis(renderer):
    """Dents at one place share the defect-free analysis (the engine groups them): a
    case's numbers are the same from its own analysis as from another dent's there."""

    def scene(sigma2, dmax):
        return PLAN.scene("sphere", 35.0, sigma2, dmax)

    case, other = scene(4.0, 0.005), scene(1.0, 0.003)
    own = measure_pmd_scene(
        renderer, case, PLAN.settings, pmd_baseline(renderer, station_model(case), PLAN.settings)
    )
    shared = measure_pmd_scene(
        renderer, case, PLAN.settings, pmd_baseline(renderer, station_model(other), PLAN.settings)
    )
    mine, theirs = summary(own), summary(shared)
    assert all(same(mine[k], theirs[k]) for k in mine)
