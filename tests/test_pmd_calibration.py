"""The station's belief (``[calibration]``) and the screen's true shape (``emitter.sag``).

The frames are rendered from the truth; a PMD station turns decoded screen points into
slopes with what it believes of its screen (plane, sag, cover glass) and camera. Each
test holds a closed form (docs/pmd.md, "The station's belief"):

- an empty calibration, or one that states the truth, changes no number, bit for bit;
- a screen point believed ``λ`` along the screen's normal ``n`` from where it is turns the
  ray from the part's point ``P`` to it by ``Δb = λ (n - (n·b) b) / L`` (``b`` the unit
  ray, ``L`` its length, ``|Δb| = |λ| sin α``, ``α`` the ray's angle to the normal), and the
  measured normal, the bisector of ``a`` (to the camera) and ``b``, by ``Δm = (Δb - (Δb·m)
  m) / |a + b|``: a flat mirror's slope error is ``-(Δm_x, Δm_z)``, ``|λ| sin α / 2L`` in
  the plane of incidence (``1 / cos i`` more across it). A believed screen distance ``D +
  δ`` is ``λ = -δ`` everywhere; a true sag believed flat is ``λ = -w(u, v)``;
- a sag believed as it is, or a cover glass believed as it is, leaves the decoding's own
  error alone.

Images are 64² of the noiseless default station (no sensor) on a flat mirror without a
dent: every slope it measures is an error.
"""

from __future__ import annotations

import numpy as np
import pytest
from tests.test_components import check_absent_code

from glshade.components.base import UniformContext
from glshade.components.emitter import plane as emitter_plane
from glshade.components.emitter.plane import sag_coefficients, sag_distance, sag_height
from glshade.errors import SceneError
from glshade.gpu.compose import ShaderFeatures
from glshade.gpu.renderer import RootSolver, scene_uniforms
from glshade.instruments.pmd.station import PmdResult, measure_pmd_scene, summary
from glshade.oracle import tracer
from glshade.scene import Scene, paper_scene

#: uv of the shader against the float64 oracle (mm), as tests/test_oracle.py.
UV_TOL = {"fp32": 5e-4, "fp64": 1e-6}
#: A sag at the limit of a 60 mm half-size screen (|bow_u| + |bow_v| + |twist| = 6 mm):
#: the 64² camera sees ±43.5 mm of it, where w reaches -1.1 to 1.6 mm.
SAG = (3.0, -2.0, 1.0)
HALF = (60.0, 60.0)
#: The default PMD station's fitted depth at 128² (µm), as the code before the station's
#: belief existed measured it (llvmpipe); within the GL-vs-oracle budget of a PMD depth
#: (tests/test_oracle_renderer.py: 2e-3 µm), so another driver's fp32 rounding passes.
DEFAULT_DEPTH_128_UM = 4.959681934248879


def station(size: int = 64, **emitter) -> Scene:
    """A PMD station over a flat mirror without a dent (θ 45°, the default coding)."""
    scene = paper_scene("flat", theta_deg=45.0, sigma2=4.0, dmax=0.0).with_size(size)
    return scene.updated(emitter={"kind": "fringes", **emitter})


def slopes(result: PmdResult) -> np.ndarray:
    """The measured slope map (H, W, 2), rad, float64."""
    return 1e-6 * result.maps.slopes_urad.astype(np.float64)


def rms(values: np.ndarray) -> float:
    """Root mean square of the vectors' lengths over the finite ones."""
    return float(np.sqrt(np.nanmean(np.sum(values**2, axis=-1))))


def first_order(scene: Scene, uv: np.ndarray, lift: np.ndarray) -> tuple[np.ndarray, ...]:
    """The slope error (H, W, 2) of a flat mirror (``y = 0``) whose screen points ``uv``
    (where they are: on the scene's screen, raised by its own sag) are believed ``lift``
    (H, W) along the screen's normal from there; with ``sin α`` and ``L`` per pixel."""
    origin, directions = scene.active.camera.pixel_rays(scene)
    o, d = np.asarray(origin, np.float64), np.asarray(directions, np.float64)
    p = o + (-o[1] / d[..., 1])[..., None] * d
    plane = scene.emitter_plane()
    n = plane.normal
    q = plane.centre + uv[..., :1] * plane.e_u + uv[..., 1:] * plane.e_v
    sag = emitter_plane.sag_of(scene)
    if sag is not None:
        coefficients = sag_coefficients(sag, scene.emitter.half_size)
        q = q + sag_height(coefficients, uv[..., 0], uv[..., 1])[..., None] * n
    a = o - p
    a /= np.linalg.norm(a, axis=-1, keepdims=True)
    length = np.linalg.norm(q - p, axis=-1, keepdims=True)
    b = (q - p) / length
    shift = lift[..., None] * n
    db = (shift - np.sum(shift * b, axis=-1, keepdims=True) * b) / length
    half = a + b
    size = np.linalg.norm(half, axis=-1, keepdims=True)
    m = half / size
    dm = (db - np.sum(db * m, axis=-1, keepdims=True) * m) / size
    gx = -(dm[..., 0] * m[..., 1] - m[..., 0] * dm[..., 1]) / m[..., 1] ** 2
    gz = -(dm[..., 2] * m[..., 1] - m[..., 2] * dm[..., 1]) / m[..., 1] ** 2
    sin_alpha = np.linalg.norm(np.cross(b, n), axis=-1)
    return np.stack([gx, gz], axis=-1), sin_alpha, length[..., 0]


# --------------------------------------------------------------------------- (a) no belief
def test_an_empty_calibration_or_the_truth_believed_changes_nothing(renderer):
    scene = Scene().with_value("emitter.kind", "fringes").with_size(128)
    today = measure_pmd_scene(renderer, scene)
    assert today.status == "ok"
    assert today.pmd_depth_um == pytest.approx(DEFAULT_DEPTH_128_UM, abs=2e-3)
    truth = [
        ("emitter.distance", scene.emitter.distance),
        ("camera.focal", scene.camera.focal),
        ("emitter.sag", (0.0, 0.0, 0.0)),
    ]
    for calibration in ([], truth):
        believed = scene.with_calibration(calibration)
        assert believed.calibration == tuple(sorted(calibration))
        again = measure_pmd_scene(renderer, believed)
        assert summary(again) == summary(today)
        for name in ("decoded", "exact", "slopes_urad", "height_um", "decoded_defect_free"):
            assert np.array_equal(
                getattr(again.maps, name), getattr(today.maps, name), equal_nan=True
            ), name
        assert np.array_equal(again.maps.heights.height_um, today.maps.heights.height_um)


@pytest.mark.parametrize(
    "calibration",
    [
        [("camera.focal", 25.1)],
        [("camera.distance", 176.6)],
        [("emitter.distance", 257.0)],
        [("emitter.pitch_deg", 0.05)],
        [("emitter.half_size", (60.5, 60.0))],
        [("emitter.sag", (0.5, 0.0, 0.0))],
        [("emitter.glass_thickness", 0.7)],
    ],
    ids=lambda pairs: pairs[0][0],
)
def test_every_belief_moves_the_slopes_and_no_frame(renderer, calibration):
    """The frames and the defect-free capture are the truth's (the same decoded points,
    bit for bit); the slopes are the belief's (they move)."""
    truth = station(half_size=HALF)
    exact = measure_pmd_scene(renderer, truth)
    believed = measure_pmd_scene(renderer, truth.with_calibration(calibration))
    for name in ("decoded", "exact", "decoded_defect_free", "exact_defect_free", "recorded"):
        assert np.array_equal(
            getattr(believed.maps, name), getattr(exact.maps, name), equal_nan=True
        ), name
    assert believed.decode_rms_mm == exact.decode_rms_mm
    assert believed.unwrap_failures == exact.unwrap_failures == 0
    assert rms(slopes(believed) - slopes(exact)) > 2e-6


# --------------------------------------------------------------------------- (b) distance
def test_a_believed_screen_distance_tilts_the_slopes_by_its_closed_form(renderer):
    delta = 1.0
    truth = station()
    believed = truth.with_calibration([("emitter.distance", truth.emitter.distance + delta)])
    exact, wrong = measure_pmd_scene(renderer, truth), measure_pmd_scene(renderer, believed)
    # one truth rendered: the same decoded points, placed on another screen
    assert np.array_equal(exact.maps.decoded, wrong.maps.decoded, equal_nan=True)
    error = slopes(wrong) - slopes(exact)
    uv = exact.maps.exact
    predicted, sin_alpha, length = first_order(truth, uv, np.full(uv.shape[:2], -delta))
    assert rms(error) > 1e-4  # 200 µrad: far above the float32 maps' rounding
    assert rms(error) == pytest.approx(rms(predicted), rel=0.1)
    assert rms(error - predicted) <= 0.1 * rms(predicted)
    # in the plane of incidence (the image's middle columns) |g| = δ sin α / 2L
    middle = slice(8, -8), slice(31, 33)
    simple = delta * sin_alpha[middle] / (2.0 * length[middle])
    measured = np.linalg.norm(error[middle], axis=-1)
    assert np.median(measured / simple) == pytest.approx(1.0, rel=0.1)
    assert np.sqrt(np.mean(measured**2)) == pytest.approx(np.sqrt(np.mean(simple**2)), rel=0.1)


# --------------------------------------------------------------------------- (c), (d) sag
def test_a_sagging_screen_believed_flat_errs_by_the_sags_closed_form(renderer):
    truth = station(half_size=HALF, sag=SAG)
    flat_belief = truth.with_calibration([("emitter.sag", (0.0, 0.0, 0.0))])
    right, wrong = measure_pmd_scene(renderer, truth), measure_pmd_scene(renderer, flat_belief)
    assert np.array_equal(right.maps.decoded, wrong.maps.decoded, equal_nan=True)
    error = slopes(wrong) - slopes(right)
    uv = right.maps.exact
    w = sag_height(sag_coefficients(SAG, HALF), uv[..., 0], uv[..., 1])
    assert np.nanmax(np.abs(w)) > 1.0
    predicted, _, _ = first_order(truth, uv, -w)
    assert rms(error) > 1e-4  # 155 µrad
    assert rms(error) == pytest.approx(rms(predicted), rel=0.1)
    assert rms(error - predicted) <= 0.1 * rms(predicted)

    # (d) believed as it is, the sag leaves the decoding's own error: a decoded point off
    # by e (its rms: decode_rms_mm) tilts a normal by about e / (2 L cos i) (L >= 237 mm,
    # i = 45°: 2.2 µrad for e = 7.4e-4 mm); the bound is twice that, and the flat screen
    # measured alike (its error is its decoding's alone) is as good
    flat = measure_pmd_scene(renderer, station(half_size=HALF))
    decoding = right.decode_rms_mm / (2.0 * 237.0 * np.cos(np.radians(45.0)))
    assert rms(slopes(right)) <= 2.0 * decoding
    assert rms(slopes(right)) <= 0.03 * rms(error)
    assert rms(slopes(right)) <= 1.5 * rms(slopes(flat))


def test_a_believed_cover_glass_undoes_the_glass(renderer):
    """Slopes through a true 1.1 mm cover glass: believed (the default: belief = truth)
    they are the bare screen's within the decoding's error; believed bare, the glass's
    offset ``t (tan i - tan r)`` tilts them by tens of µrad. With a sag too."""
    bare = measure_pmd_scene(renderer, station(half_size=HALF))
    floor = 2.0 * rms(slopes(bare))
    for sag in ((0.0, 0.0, 0.0), SAG):
        glass = station(half_size=HALF, glass_thickness=1.1, sag=sag)
        right = measure_pmd_scene(renderer, glass)
        wrong = measure_pmd_scene(
            renderer, glass.with_calibration([("emitter.glass_thickness", 0.0)])
        )
        assert rms(slopes(right)) <= floor, sag
        assert rms(slopes(wrong)) > 10.0 * floor, sag


# --------------------------------------------------------------------------- the shader
@pytest.mark.parametrize("precision", ["fp32", "fp64"])
@pytest.mark.parametrize(
    "emitter",
    [{"kind": "stripes"}, {"kind": "fringes"}, {"kind": "fringes", "glass_thickness": 1.1}],
    ids=["stripes", "fringes", "fringes-glass"],
)
def test_the_shader_lands_on_the_sagging_screen_as_the_oracle(renderer, precision, emitter):
    flat = paper_scene("flat", theta_deg=35.0, dmax=0.0).with_size(64)
    flat = flat.updated(emitter={**emitter, "half_size": HALF}, render={"precision": precision})
    sagging = flat.updated(emitter={"sag": SAG})
    assert sagging.active.features(sagging)["screen_sag"]
    assert not flat.active.features(flat)["screen_sag"]
    shader, oracle = renderer.render(sagging, ("uv", "mask")), tracer.trace(sagging, ("uv", "mask"))
    both = shader.mask & oracle.mask
    assert both.sum() > 3000
    uv = shader.uv.astype(np.float64)
    assert np.abs(uv - oracle.uv)[both].max() <= UV_TOL[precision]
    # the sag moves each point by (w / r·n) (r·e_u, r·e_v) to first order (w ≤ 1.6 mm here;
    # the second order, w |∇w| tan α, stays below 5e-3 mm)
    before = tracer.trace(flat, ("uv",)).uv
    moved = oracle.uv - before
    assert np.nanmax(np.abs(moved)) > 0.1
    origin, directions = flat.active.camera.pixel_rays(flat)
    d = np.asarray(directions, np.float64)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    r = d * np.array([1.0, -1.0, 1.0])  # the flat mirror's reflection
    plane = flat.emitter_plane()
    w = sag_height(sag_coefficients(SAG, HALF), before[..., 0], before[..., 1])
    lean = np.stack([r @ plane.e_u, r @ plane.e_v], axis=-1)
    expected = (w / (r @ plane.normal))[..., None] * lean
    assert np.nanmax(np.abs(moved - expected)) < 5e-3


def test_the_hits_newton_steps_converge():
    """Three Newton steps from the plane's hit land within 1e-9 mm of the sagging surface
    (twelve steps: the surface itself) for the largest sag allowed, within 45° of the
    normal; the residual ``d r·n - gap - w`` is ~0 there."""
    rng = np.random.default_rng(3)
    count = 20000
    half = (150.0, 150.0)
    for sag in ((15.0, 0.0, 0.0), (7.5, 5.0, 2.5), (0.0, 0.0, -15.0), (1.0, 0.0, 0.0)):
        coefficients = sag_coefficients(sag, half)
        target = rng.uniform(-1.0, 1.0, (count, 2)) * np.asarray(half)
        tilt, turn = np.radians(rng.uniform(0.0, 45.0, count)), rng.uniform(0, 2 * np.pi, count)
        lean = (np.sin(tilt) * np.cos(turn), np.sin(tilt) * np.sin(turn))
        facing, gap = -np.cos(tilt), np.full(count, -250.0)
        reach = 250.0 / np.cos(tilt)  # to the plane, from 250 mm in front of it
        foot = (target[:, 0] - reach * lean[0], target[:, 1] - reach * lean[1])
        d = sag_distance(coefficients, foot, lean, facing, gap, gap / facing)
        u, v = foot[0] + d * lean[0], foot[1] + d * lean[1]
        residual = d * facing - gap - sag_height(coefficients, u, v)
        assert np.abs(residual).max() < 1e-9, sag


def test_the_filtered_footprint_follows_the_sagging_screen(renderer):
    """A Blinn-Phong lobe (the shader's closed form, its footprint the emitter's Jacobian
    on the sagging screen's tangent plane) against the oracle's quadrature over the
    sagging screen: as close as over a flat one (the flat plane's Jacobian: 1.5 times)."""
    errors = {}
    for sag in ((0.0, 0.0, 0.0), SAG):
        scene = paper_scene("flat", theta_deg=35.0, dmax=0.0).with_size(24)
        scene = scene.updated(
            emitter={
                "kind": "fringes",
                "sag": sag,
                "half_size": HALF,
                "periods": (6.0, 48.0, 384.0),
            },
            render={"precision": "fp64", "reflection": "blinn-phong", "shininess": 1e6},
        )
        shader = renderer.render(scene, ("image", "mask"))
        oracle = tracer.trace(scene, ("image", "mask"))
        both = shader.mask & oracle.mask
        errors[sag] = float(np.sqrt(np.mean((shader.image - oracle.image)[both] ** 2)))
    assert errors[SAG] <= 1.15 * errors[(0.0, 0.0, 0.0)]


# --------------------------------------------------------------------------- the program
@pytest.mark.parametrize("reflection", ["mirror", "blinn-phong", "ggx"])
@pytest.mark.parametrize("glass", [0.0, 1.1])
def test_a_sagging_screens_uniforms_and_code(renderer, reflection, glass):
    """The sag's uniform is provided where its code is, and used; without a sag neither
    is there (the project's absent-code check)."""
    base = paper_scene("flat", theta_deg=30.0).with_size(12)
    base = base.updated(
        emitter={"kind": "fringes", "glass_thickness": glass}, render={"reflection": reflection}
    )
    for scene in (base, base.updated(emitter={"sag": (0.5, -0.3, 0.2)})):
        sags = scene.active.features(scene)["screen_sag"]
        for outputs in (("image",), ("uv", "mask"), ("image", "uv", "mask", "distance")):
            check_absent_code(scene, outputs)
            features = ShaderFeatures.from_scene(scene, outputs)
            program = renderer.program(features)
            active = {n for n in program if n.startswith("u_") and hasattr(program[n], "value")}
            provided = scene_uniforms(scene, RootSolver(), features, ())
            assert active <= set(provided)
            context = UniformContext(
                scene.local_origin(), features.template_variables(), RootSolver(), ()
            )
            own = scene.active.emitter.uniforms(scene, context)
            assert ("u_emitter_sag" in own) == sags == ("u_emitter_sag" in active)


# --------------------------------------------------------------------------- the table
def test_the_sag_is_a_quiet_bounded_vector_and_a_belief(tmp_path):
    scene = Scene()
    assert scene.emitter.sag == (0.0, 0.0, 0.0)
    assert "sag" not in scene.to_dict()["emitter"]  # quiet: rig files do not change
    with pytest.raises(SceneError, match=r"emitter\.sag.*<= 15 mm"):
        scene.with_value("emitter.sag", (10.0, -5.0, 1.0))
    bent = station(half_size=HALF, sag=SAG).with_calibration(
        [("emitter.sag", (0.0, 0.0, 0.0)), ("emitter.distance", 257.0)]
    )
    path = tmp_path / "bent.toml"
    bent.save(path)
    text = path.read_text()
    assert "[calibration]" in text and "sag = [" in text
    loaded = Scene.load(path)
    assert loaded == bent
    assert loaded.believed().emitter.sag == (0.0, 0.0, 0.0)
    assert loaded.believed().emitter.distance == 257.0
    assert loaded.emitter.sag == SAG
    with pytest.raises(SceneError, match=r"calibration\.emitter\.sag"):
        bent.with_calibration([("emitter.sag", (7.0, 0.0, 0.0))])
