"""The PMD shift's closed form (docs/physics.md, "The PMD shift on a curved base") against
the exact screen points the float64 oracle traces, and its caveat at grazing views.

The traced shift is taken as ``pmd_shift_exact_mm`` takes it (the largest move of a
pixel's exact screen point, pixels beside unseen ones left out), over the column of
pixels through the dent along the plane of incidence of the paper's camera at 1024 px:
a symmetric dent's largest move lies there, and a column is a few hundred rays, so each
case takes a fraction of a second. One case is also measured end to end by the GL
station at 128 px."""

from __future__ import annotations

import math

import numpy as np
import pytest

from glshade.instruments.pmd.settings import PmdSettings
from glshade.instruments.pmd.station import measure_pmd_scene
from glshade.measure.single import as_method
from glshade.metrics import physics
from glshade.metrics.status import dent_window
from glshade.oracle.tracer import trace
from glshade.scene import paper_scene

COLUMN_SIZE = 1024


def station(surface: str, theta: float, sigma2: float, dmax: float = 0.005, **surface_keys):
    """The paper's case as a PMD station sees it (both directions coded)."""
    scene = paper_scene(surface, theta, sigma2, dmax)
    if surface_keys:
        scene = scene.updated(surface=surface_keys)
    return as_method(scene, "pmd")


def traced_shift_mm(scene) -> float:
    """The largest move of the exact screen point over the dent's window in the central
    column (1024 px across), pixels next to one that sees no screen left out."""
    scene = scene.with_size(COLUMN_SIZE)
    rows = np.flatnonzero(dent_window(scene, (COLUMN_SIZE, COLUMN_SIZE)).any(axis=1))
    middle = COLUMN_SIZE // 2
    window = {"rows": slice(rows[0], rows[-1] + 1), "cols": slice(middle, middle + 1)}
    dented = trace(scene, ("uv",), **window).uv[:, 0]
    nominal = trace(scene.without_defect(), ("uv",), **window).uv[:, 0]
    moved = np.linalg.norm(dented - nominal, axis=-1)
    seen = np.isfinite(moved)
    inner = seen & np.r_[False, seen[:-2] & seen[2:], False]
    return float(np.max(moved[inner]))


def flat_law_mm(scene) -> float:
    """``2 α (De + σ cos θ)`` written out (the isotropic dent's σ)."""
    sigma = math.sqrt(scene.defect.sigma_z2)
    alpha = abs(scene.defect.dmax) * math.exp(-0.5) / sigma
    return 2.0 * alpha * (scene.emitter.distance + sigma * math.cos(scene.camera.theta_rad))


@pytest.mark.parametrize("theta", [5.0, 25.0, 45.0, 85.0])
@pytest.mark.parametrize("surface", ["flat", "cylinder"])
def test_without_curvature_along_the_plane_the_law_is_the_flat_one(surface, theta):
    """The flat plate and the paper's cylinder (axis in the plane of incidence, κ_t = 0):
    the law is 2 α (De + σ cos θ), to the last bit, and holds (no caveat)."""
    for sigma2 in (1.0, 16.0):
        scene = station(surface, theta, sigma2)
        assert physics.curved_base_factor(scene, math.sqrt(sigma2)) == 1.0
        assert physics.pmd_shift_mm(scene) == flat_law_mm(scene)
        assert physics.pmd_shift_law_check(scene) == physics.LawCheck()


@pytest.mark.parametrize("theta", [15.0, 45.0, 85.0])
def test_on_the_flat_plate_the_trace_is_the_law_plus_the_depth_offset(theta):
    """On the flat plate the traced shift is the law plus the one term it leaves out:
    the dent's depth moves the hit point along the camera ray, which offsets the
    reflected ray by 2 |D| cos θ, so the trace is 2 α (De + 2 σ cos θ), within 0.2 %."""
    for sigma2 in (1.0, 16.0):
        scene = station("flat", theta, sigma2)
        sigma, cos_t = math.sqrt(sigma2), math.cos(math.radians(theta))
        de = scene.emitter.distance
        with_depth = physics.pmd_shift_mm(scene) * (de + 2 * sigma * cos_t) / (de + sigma * cos_t)
        assert traced_shift_mm(scene) == pytest.approx(with_depth, rel=2e-3)


@pytest.mark.parametrize("theta", [25.0, 35.0, 45.0, 65.0, 85.0])
def test_on_the_sphere_the_law_holds_from_25_to_85_degrees(theta):
    """The sphere R 70 mm, the paper's dents: within 2 % of the traced shift (measured:
    at most +1.4 %, the depth offset the law leaves out), where the flat law fell short
    by up to 14 % (which this bound would catch at θ 25°, σ² 16)."""
    for sigma2 in (1.0, 4.0, 16.0):
        scene = station("sphere", theta, sigma2)
        assert physics.pmd_shift_law_check(scene).status == "ok"
        traced = traced_shift_mm(scene)
        law = physics.pmd_shift_mm(scene)
        assert 0.995 < traced / law < 1.02, (sigma2, traced, law)
        if theta == 25.0 and sigma2 == 16.0:
            assert traced / flat_law_mm(scene) > 1.1  # what the curvature adds


def test_a_convex_base_across_the_plane_bends_the_law_too():
    """A cylinder with its axis across the plane of incidence has κ_t = -1/R like the
    sphere: the same law, within 2 % of the trace at θ 25° and 45°."""
    for theta in (25.0, 45.0):
        scene = station("cylinder", theta, 16.0, axis="x")
        assert physics.pmd_shift_mm(scene) > 1.05 * flat_law_mm(scene)
        assert traced_shift_mm(scene) / physics.pmd_shift_mm(scene) == pytest.approx(1.0, abs=0.02)


def test_grazing_views_carry_a_caveat():
    """Where the base's horizon falls inside the dent's window the law says so: the
    sphere at θ 5° for σ² 16 (elevation 5° - 12 mm x (1/70 + sin 5°/175.6) < 0), not for
    σ² 1 (its 3 mm window stays above the horizon, and the law holds there to 1 %). On a
    tighter sphere (R 30 mm) at θ 10° the traced shift exceeds the law by a fifth at
    1024 px (by two fifths at 2048: the nearer the pixels reach the horizon, the more):
    the caveat is what marks it."""
    grazing = physics.pmd_shift_law_check(station("sphere", 5.0, 16.0))
    assert grazing.status == "grazing"
    assert "-5.2°" in grazing.reason and "±3 σ (12 mm)" in grazing.reason
    steep = station("sphere", 5.0, 1.0)
    assert physics.pmd_shift_law_check(steep).status == "ok"
    assert traced_shift_mm(steep) / physics.pmd_shift_mm(steep) == pytest.approx(1.0, abs=0.01)
    tight = station("sphere", 10.0, 16.0, radius=30.0)
    assert physics.pmd_shift_law_check(tight).status == "grazing"
    assert traced_shift_mm(tight) > 1.15 * physics.pmd_shift_mm(tight)


def test_the_station_measures_the_law_on_the_sphere(_session_renderer):
    """End to end at 128 px, no sensor: the GL station's exact shift on the sphere at
    θ 25°, σ² 16 within 3 % of the law (the flat law: 14 % below it)."""
    scene = station("sphere", 25.0, 16.0).with_size(128)
    result = measure_pmd_scene(_session_renderer, scene, PmdSettings())
    assert result.status == "ok"
    law = physics.pmd_shift_mm(scene)
    assert result.pmd_shift_exact_mm == pytest.approx(law, rel=0.03)
    assert result.pmd_shift_exact_mm > 1.1 * flat_law_mm(scene)
