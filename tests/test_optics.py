"""Issue 12: each optical model against an independent computation.

- the thin lens against the analytic circle of confusion on a flat mirror (the stripes
  convolved with the aperture's disc projected onto the emitter), its pinhole limit, and
  the sharp image when focused on the stripes' mirror image;
- distortion against ``cv2.projectPoints`` / ``cv2.undistortPointsIter``, folding refused;
- the microfacet lobes against the NumPy oracle's Monte-Carlo, and their mirror limit;
- eq. (1)'s coherent fraction and its Lambertian remainder (polygon formula against
  quadrature);
- Fresnel against tabulated reflectances;
- the sensor's noise statistics on a uniform image, and the metric's noise floor.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from tests.test_components import check_absent_code

from glshade.components.camera.perspective.optics import distort, undistort
from glshade.components.registry import registry
from glshade.errors import SceneError
from glshade.instruments.record import Measurement
from glshade.instruments.stripes.single import measure_scene, shades_from_map
from glshade.oracle import tracer
from glshade.scene import Scene, paper_scene


def j1(x: float) -> float:
    """Bessel's J1 by its integral (1/π) ∫₀^π cos(τ - x sin τ) dτ (midpoint rule, exact to
    ~1e-15 for a periodic integrand)."""
    tau = (np.arange(2000) + 0.5) * math.pi / 2000
    return float(np.mean(np.cos(tau - x * np.sin(tau))))


def flat(theta: float = 45.0, size: int = 256) -> Scene:
    return paper_scene("flat", theta, 4.0, 0.005).without_defect().with_size(size)


# ------------------------------------------------------------------ thin lens
def disc_blurred(v: np.ndarray, scene: Scene, radius_mm: float) -> np.ndarray:
    """The stripe radiance at ``v`` convolved with a uniform disc of ``radius_mm`` seen
    edge-on (its marginal along v: a semicircle), by 4001-point quadrature."""
    t = np.linspace(-radius_mm, radius_mm, 4001)
    kernel = np.sqrt(np.maximum(radius_mm**2 - t**2, 0.0))
    kernel /= kernel.sum()
    radiance = tracer.radiance(scene.emitter, v[:, None] - t[None, :])
    return radiance @ kernel


@pytest.mark.parametrize("f_number", [16.0, 32.0])
def test_thin_lens_blurs_the_stripes_by_the_circle_of_confusion(renderer, f_number):
    """Focused on the surface, a point of the flat mirror's emitter image lies De beyond
    it: its blur disc on the emitter has the diameter A De / Dc (A = focal / N)."""
    scene = flat()
    lens = scene.updated(camera={"f_number": f_number, "aperture_samples": 1024})
    v0 = renderer.render(scene, ("uv",)).uv[:, 128, 1].astype(np.float64)
    image = renderer.render(lens).image[:, 128].astype(np.float64)
    cam = scene.camera
    radius = 0.5 * (cam.focal / f_number) * scene.emitter.distance / cam.distance
    rows = slice(96, 160)  # near the centre, where the emitter is seen square-on
    expected = disc_blurred(v0[rows], scene, radius)
    assert np.abs(image[rows] - expected).max() < 4e-3
    # the stripes' contrast falls by the disc's transfer function, 2 J1(kR) / (kR)
    k = 2.0 * math.pi / scene.emitter.period
    pinhole = tracer.radiance(scene.emitter, v0[rows])
    contrast = (image[rows].max() - image[rows].min()) / (pinhole.max() - pinhole.min())
    first_harmonic = 2.0 * j1(k * radius) / (k * radius)
    assert contrast == pytest.approx(abs(first_harmonic), abs=0.08)
    assert contrast < 0.9


def test_thin_lens_tends_to_the_pinhole_and_is_sharp_on_the_stripes(renderer):
    scene = flat(size=64)
    pinhole = renderer.render(scene).image
    tiny = renderer.render(scene.updated(camera={"f_number": 1e6, "aperture_samples": 16})).image
    assert np.abs(tiny - pinhole).max() < 1e-4
    # focused on the stripes' mirror image (Dc + De along the axis) a flat mirror is sharp
    far = scene.camera.distance + scene.emitter.distance
    sharp = renderer.render(
        scene.updated(camera={"f_number": 2.8, "focus_distance": far, "aperture_samples": 64})
    )
    assert np.abs(sharp.image - pinhole).max() < 2e-3
    blurred = renderer.render(scene.updated(camera={"f_number": 2.8, "aperture_samples": 64})).image
    assert np.abs(blurred - pinhole).max() > 0.3


def test_thin_lens_agrees_with_the_oracle(renderer):
    scene = (
        paper_scene("flat", 30.0, 2.0, 0.005)
        .with_size(24)
        .updated(camera={"f_number": 8.0, "aperture_samples": 16, "focus_distance": 300.0})
    )
    for precision, tol in (("fp32", 2e-4), ("fp64", 1e-6)):
        s = scene.updated(render={"precision": precision})
        shader, oracle = (
            renderer.render(s, ("image", "uv", "mask")),
            tracer.trace(s, ("image", "uv", "mask")),
        )
        assert (shader.mask == oracle.mask).all()
        assert np.abs(shader.image - oracle.image).max() < tol * 10
        assert np.nanmax(np.abs(shader.uv - oracle.uv)) < max(
            tol, 5e-4 if precision == "fp32" else 0
        )


# ------------------------------------------------------------------ distortion
CALIBRATED = (-0.21, 0.08, 0.0012, -0.0009, -0.015)  # a typical cv2.calibrateCamera result


def camera_matrix(scene: Scene) -> np.ndarray:
    cam = scene.camera
    f = cam.focal / cam.pixel_pitch
    return np.array(
        [[f, 0.0, cam.width / 2 - 0.5], [0.0, f, cam.height / 2 - 0.5], [0.0, 0.0, 1.0]]
    )


def test_distorted_rays_project_back_onto_their_pixels():
    """cv2.projectPoints of each pixel's ray (in OpenCV's camera frame: x right, y down,
    z forward) lands on the pixel's centre."""
    scene = flat(30.0, 48).updated(camera={"distortion": list(CALIBRATED)})
    _, d = registry().active(scene).camera.pixel_rays(scene)
    forward, right, up = scene.camera.basis()
    points = np.stack([d @ right, -(d @ up), d @ forward], axis=-1).reshape(-1, 1, 3)
    projected, _ = cv2.projectPoints(
        points, np.zeros(3), np.zeros(3), camera_matrix(scene), np.array(CALIBRATED)
    )
    rows, cols = np.mgrid[0:48, 0:48]
    expected = np.stack([cols, rows], axis=-1).reshape(-1, 1, 2)
    assert np.abs(projected - expected).max() < 1e-6


def test_undistortion_matches_opencv():
    pixels = np.random.default_rng(3).uniform(0, 1024, (500, 1, 2))
    scene = flat(30.0, 1024)
    k = camera_matrix(scene)
    criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14)
    ours = np.stack(
        undistort(
            CALIBRATED, (pixels[..., 0] - k[0, 2]) / k[0, 0], (pixels[..., 1] - k[1, 2]) / k[1, 1]
        ),
        axis=-1,
    )
    theirs = cv2.undistortPoints(pixels, k, np.array(CALIBRATED), None, None, None, criteria)
    assert np.abs(ours - theirs).max() * k[0, 0] < 1e-6  # pixels
    back = np.stack(distort(CALIBRATED, ours[..., 0], ours[..., 1]), axis=-1)
    assert np.abs(back * k[0, 0] + k[:2, 2] - pixels).max() < 1e-8


def test_distortion_agrees_with_the_oracle_and_bends_lines(renderer):
    scene = paper_scene("flat", 30.0, 2.0, 0.005).with_size(32)
    bent = scene.updated(camera={"distortion": list(CALIBRATED)})
    for precision, tol in (("fp32", 5e-4), ("fp64", 1e-6)):
        s = bent.updated(render={"precision": precision})
        shader, oracle = renderer.render(s, ("uv", "mask")), tracer.trace(s, ("uv", "mask"))
        assert (shader.mask == oracle.mask).all()
        assert np.nanmax(np.abs(shader.uv - oracle.uv)) < tol
    # barrel distortion pulls the corners in: a corner pixel sees further out
    straight = renderer.render(scene, ("uv",)).uv
    assert abs(renderer.render(bent, ("uv",)).uv[0, 0, 0]) > abs(straight[0, 0, 0]) * 1.002


def test_a_distortion_that_folds_inside_the_sensor_is_refused():
    with pytest.raises(
        SceneError, match="camera.distortion: must be coefficients whose map does not fold"
    ):
        flat().updated(camera={"distortion": [-20.0, 0.0, 0.0, 0.0, 0.0]})
    # the same coefficient on a narrower sensor folds outside it: accepted
    flat().updated(
        camera={
            "width": 512,
            "height": 512,
            "pixel_pitch": 0.005,
            "distortion": [-20.0, 0.0, 0.0, 0.0, 0.0],
        }
    )


# ------------------------------------------------------------------ microfacets
def _hits(scene: Scene, rows: slice, cols: slice):
    from glshade.oracle.tracer import _first_hit_rays, _normals

    parts = registry().active(scene)
    origins, dirs = parts.camera.sample_rays(scene, rows, cols, 1)
    o, d = np.ascontiguousarray(origins.reshape(-1, 3)), dirs.reshape(-1, 3)
    t, hit = _first_hit_rays(scene, o, d)
    assert hit.all()
    p = o + t[:, None] * d
    return parts, p, d, _normals(scene, parts, p[:, 0], p[:, 2])


@pytest.mark.parametrize("lobe", ["beckmann", "ggx"])
def test_microfacet_lobes_agree_with_monte_carlo(renderer, lobe):
    """The closed form and the lattice against the oracle's Monte-Carlo (2^16 samples a
    pixel): within 4 standard errors plus the method's own error."""
    scene = (
        paper_scene("flat", 30.0, 4.0, 0.005)
        .with_size(32)
        .updated(render={"reflection": lobe, "roughness": 0.002})
    )
    rows, cols = slice(14, 18), slice(12, 20)
    parts, p, d, n = _hits(scene, rows, cols)
    mean, error = parts.reflection.monte_carlo(scene, p, d, n, 1 << 16, 11)
    assert 0.05 < mean.max() - mean.min()  # the stripes are still there
    closed = renderer.render(scene).image[rows, cols].ravel()
    assert np.abs(closed - mean).max() < 4 * error.max() + 1e-3
    lattice = renderer.render(
        scene.updated(render={"lobe_method": "lattice", "lobe_samples": 1024})
    ).image
    assert np.abs(lattice[rows, cols].ravel() - mean).max() < 4 * error.max() + 1e-2


@pytest.mark.parametrize("lobe", ["beckmann", "ggx"])
@pytest.mark.parametrize("method", ["closed", "lattice"])
def test_microfacet_tends_to_the_mirror(renderer, lobe, method):
    scene = flat(30.0, 48)
    mirror = renderer.render(scene).image
    rough = scene.updated(
        render={"reflection": lobe, "roughness": 1e-6, "lobe_method": method, "lobe_samples": 16}
    )
    assert np.abs(renderer.render(rough).image - mirror).max() < 2e-3
    wider = renderer.render(rough.updated(render={"roughness": 0.003})).image
    assert np.ptp(wider) < 0.8 * np.ptp(mirror)  # a rough lobe washes the stripes out


# ------------------------------------------------------------------ eq. (1)
def test_eq1_mirror_and_its_lambertian_remainder_agree_with_the_oracle(renderer):
    scene = (
        paper_scene("flat", 20.0, 4.0, 0.005).with_size(24).updated(render={"height_rms_um": 0.04})
    )
    shader, oracle = renderer.render(scene), tracer.trace(scene, ("image",))
    assert np.abs(shader.image - oracle.image).max() < 2e-4


def test_eq1_turns_a_rough_finish_into_a_mirror_at_grazing_views(renderer):
    """The same finish: mostly scattered seen from above, mostly coherent from the side."""

    def contrast(theta):
        """The stripes' contrast with eq. (1) over the mirror's, in the central 8 x 8 pixels
        (the Lambertian remainder is smooth there)."""
        scene = flat(theta, 256)
        rough = renderer.render(scene.updated(render={"height_rms_um": 0.05})).image[
            124:132, 124:132
        ]
        return float(np.ptp(rough) / np.ptp(renderer.render(scene).image[124:132, 124:132]))

    high, low = contrast(85.0), contrast(5.0)
    k = 4 * math.pi * 0.05 / 0.55
    assert high == pytest.approx(math.exp(-((k * math.sin(math.radians(85.0))) ** 2)), abs=0.01)
    assert low == pytest.approx(math.exp(-((k * math.sin(math.radians(5.0))) ** 2)), abs=0.01)
    assert low > 0.95 and high < 0.4


# ------------------------------------------------------------------ Fresnel
#: (n, k, incidence deg, reflectance): glass n = 1.5 (Hecht, Optics, table 4.1 values:
#: Rs(45°) = 0.0920, Rp(45°) = 0.0085, Rs at Brewster's 56.31° = 0.1479), and aluminium
#: at 550 nm (n 0.958, k 6.69: 91.6 % at normal incidence).
FRESNEL_TABLE = [
    (1.5, 0.0, 0.1, 0.04),
    (1.5, 0.0, 45.0, 0.5 * (0.0920 + 0.0085)),
    (1.5, 0.0, 56.31, 0.5 * 0.1479),
    (0.958, 6.69, 0.1, 0.9211),
]


@pytest.mark.parametrize("n, k, incidence, expected", FRESNEL_TABLE)
def test_fresnel_against_tabulated_values(renderer, n, k, incidence, expected):
    kind = "conductor" if k else "dielectric"
    scene = flat(max(0.2, 90.0 - incidence), 32).updated(
        render={"fresnel": kind, "ior": n, "extinction": k}
    )
    component = registry().active(scene).fresnel
    cos_i = math.cos(math.radians(incidence))
    assert float(component.reflectance(scene, np.array([cos_i]))[0]) == pytest.approx(
        expected, abs=2e-3
    )
    # the shader at the gaze point: radiance x R(theta_i) (incidence = 90 - theta there)
    if incidence < 89.0:
        mirror = renderer.render(flat(90.0 - incidence, 32).updated(emitter={"phase": 0.0})).image
        with_fresnel = renderer.render(scene.updated(emitter={"phase": 0.0})).image
        ratio = with_fresnel[14:18, 14:18] / mirror[14:18, 14:18]
        assert np.allclose(ratio, expected, atol=3e-3)


# ------------------------------------------------------------------ sensor
def test_sensor_noise_statistics_on_a_uniform_image():
    scene = flat(size=8).updated(
        camera={"exposure": 1.0},
        sensor={
            "full_well_e": 10000.0,
            "read_noise_e": 5.0,
            "bit_depth": 16,
            "seed": 4,
            "black_level_dn": 0,  # the statistics without an offset (test_sensor_black_level)
        },
    )
    sensor = registry().active(scene).sensor
    uniform = np.full((400, 400), 0.5, np.float32)
    image = sensor.develop(scene, uniform).astype(np.float64)
    expected_var = (0.5 * 10000.0 + 25.0) / 1e8 + 1.0 / (12.0 * 65535.0**2)
    assert image.mean() == pytest.approx(0.5, abs=3e-4)
    assert image.var() == pytest.approx(expected_var, rel=0.03)
    # bit depth: 8 bits store multiples of 1/255; the full well clips at 1
    coarse = sensor.develop(
        scene.updated(sensor={"bit_depth": 8}), np.full((50, 50), 2.0, np.float32)
    )
    assert (coarse == 1.0).all()
    eight = sensor.develop(scene.updated(sensor={"bit_depth": 8}), uniform)
    assert np.allclose(eight * 255.0, np.round(eight * 255.0), atol=1e-4)
    # deterministic in the seed, independent between exposures and seeds
    assert np.array_equal(sensor.develop(scene, uniform), sensor.develop(scene, uniform))
    assert not np.array_equal(
        sensor.develop(scene, uniform), sensor.develop(scene, uniform, exposure=1)
    )
    assert not np.array_equal(
        sensor.develop(scene, uniform), sensor.develop(scene.updated(sensor={"seed": 5}), uniform)
    )
    # the exposure scales the photons: 1.5 puts 0.5 at 0.75 of full scale; "auto" puts the
    # brightest value at 0.9
    brighter = sensor.develop(scene.updated(camera={"exposure": 1.5}), uniform)
    assert brighter.mean() == pytest.approx(0.75, abs=3e-4)
    auto = sensor.develop(scene.updated(camera={"exposure": "auto"}), uniform)
    assert auto.mean() == pytest.approx(0.9, abs=3e-4)


def test_sensor_table_switches_it_on_and_round_trips(tmp_path):
    assert not Scene().sensor.on and "sensor" not in Scene().to_dict()
    path = tmp_path / "s.toml"
    path.write_text("[sensor]\nseed = 3\n")
    scene = Scene.load(path)
    assert scene.sensor.on and scene.sensor.full_well_e == 10000.0 and scene.sensor.seed == 3
    changed = scene.updated(sensor={"full_well_e": 5000.0}).updated(sensor={"seed": 9})
    assert changed.sensor.full_well_e == 5000.0  # changing one key keeps the others
    scene.save(tmp_path / "t.toml")
    assert Scene.load(tmp_path / "t.toml") == scene
    assert not shades_from_map(scene) and shades_from_map(Scene())


def test_renderer_image_is_the_sensor_image(renderer):
    scene = flat(size=32).updated(sensor={"bit_depth": 8})
    noiseless = renderer.render(scene.updated(sensor={"full_well_e": None})).image
    recorded = renderer.render(scene).image
    # "auto" exposure: the defect-free scene's brightest point at 0.9 of full scale
    gain = renderer.exposure_gain(scene)
    normal = renderer.render(scene.without_defect().updated(sensor={"full_well_e": None})).image
    assert gain == pytest.approx(0.9 / np.nanmax(normal))
    exposed = scene.with_value("camera.exposure", gain)
    assert np.array_equal(recorded, registry().active(scene).sensor.develop(exposed, noiseless))
    assert 0 < np.abs(recorded - gain * noiseless).max() < 0.1


def test_sensor_noise_floor_is_reported(renderer):
    scene = (
        paper_scene("flat", 45.0, 4.0, 0.005)
        .with_size(256)
        .updated(sensor={"full_well_e": 2000.0, "read_noise_e": 10.0, "bit_depth": 12})
    )
    result = measure_scene(renderer, scene)
    assert result.noise_floor_px is not None and 0.0 < result.noise_floor_px < result.visibility_px
    assert Measurement.of(scene, result).noise_floor_px == result.noise_floor_px
    assert (
        measure_scene(renderer, scene.updated(sensor={"full_well_e": None})).noise_floor_px is None
    )


def test_fresnel_keeps_the_visibility_through_the_image_level(renderer):
    """A clear coat reflects 5 % at 45°: the threshold follows the image's range, so the
    contours (and the visibility) are the mirror's."""
    scene = paper_scene("flat", 45.0, 4.0, 0.005).with_size(256)
    mirror = measure_scene(renderer, scene)
    coated = measure_scene(renderer, scene.updated(render={"fresnel": "dielectric"}))
    assert coated.visibility_px == pytest.approx(mirror.visibility_px, abs=1.0)


# ------------------------------------------------------------------ shader code
FEATURE_SCENES = {
    "lens": {"camera": {"f_number": 4.0}},
    "distortion": {"camera": {"distortion": list(CALIBRATED)}},
    "lens+distortion": {"camera": {"f_number": 4.0, "distortion": list(CALIBRATED)}},
    "beckmann-closed": {"render": {"reflection": "beckmann", "roughness": 0.001}},
    "ggx-lattice": {"render": {"reflection": "ggx", "roughness": 0.001, "lobe_method": "lattice"}},
    "ggx-sampling+eq1": {
        "render": {"reflection": "ggx", "lobe_method": "sampling", "height_rms_um": 0.02}
    },
    "mirror+eq1": {"render": {"height_rms_um": 0.02}},
    "blinn+eq1": {"render": {"reflection": "blinn-phong", "height_rms_um": 0.02}},
    "conductor": {"render": {"fresnel": "conductor", "extinction": 3.0}},
    "sensor": {"sensor": {}},
}


@pytest.mark.parametrize("name", list(FEATURE_SCENES))
def test_each_feature_brings_its_code_and_nothing_else(renderer, name):
    scene = flat(30.0, 16).updated(**FEATURE_SCENES[name])
    for outputs in (("image",), ("uv", "mask"), ("image", "uv", "mask")):
        check_absent_code(scene, outputs)
    renderer.render(scene, ("image", "uv", "mask"))  # compiles and runs


# ------------------------------------------------------------------ the finding-3 study
@pytest.mark.slow
def test_finding3_study_writes_its_report_and_the_study_quotes_it(tmp_path):
    from glshade.study import finding3 as optics

    chosen = (optics.VARIANTS[0], optics.VARIANTS[4], optics.VARIANTS[5])  # mirror, Fresnel, sensor
    report = optics.run(
        tmp_path, size=256, variants=chosen, thetas=(85.0, 45.0, 5.0), sigma2s=(4.0, 9.0, 16.0)
    )
    text = report.read_text()
    assert "# Finding 3 under realistic optics" in text and "## Noise floor" in text
    rows = optics.read_rows(tmp_path / "finding3.csv")
    assert len(rows) == 3 * 3 * 3 and (tmp_path / "finding3.png").stat().st_size > 1000
    sensor_rows = [r for r in rows if r["variant"] == "sensor"]
    assert all(r["noise_floor_px"] is not None for r in sensor_rows)
    assert all(r["noise_floor_px"] is None for r in rows if r["variant"] == "mirror")
    section = optics.report_section(tmp_path)
    assert (
        section[0] == "## Finding 3 under realistic optics"
        and sum("finding 3 " in line for line in section) >= 3
    )
