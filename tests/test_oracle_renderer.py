"""The NumPy oracle as a renderer (:class:`glshade.oracle.renderer.OracleRenderer`): the GL
renderer's outputs in its types, and the numbers the measuring code makes of them the GL
renderer's within the fp32 error budget: the paper's metric, phase measuring, a sensor.

The tolerances were measured on llvmpipe (GL fp32 against the oracle's float64), with a
margin of about 3: image 2.8e-5 of the peak, uv 1.1e-4 mm on the emitter, hit distance 3e-4
mm (at about 175 mm); the paper's continuous numbers 6.2e-5 px; PMD lengths 2.7e-5 mm (and
their rounding to 4 digits), depths 2e-4 µm, slopes 0.03 µrad."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import glshade
from glshade.errors import GlshadeError
from glshade.frame import Frame
from glshade.instruments.record import Measurement, PmdMeasurement
from glshade.instruments.stripes.single import measure_scene
from glshade.oracle import tracer
from glshade.oracle.renderer import DEFAULT_MAX_PIXELS, OracleRenderer, geometry_key
from glshade.scene import Scene, paper_scene

SENSOR = {"full_well_e": 10000.0, "read_noise_e": 5.0, "bit_depth": 12}
OUTPUTS = ("image", "uv", "mask", "distance", "rays")
#: GL fp32 against the oracle: image (share of the emitter's peak), uv (mm), distance (mm).
IMAGE_TOL, UV_TOL, DISTANCE_TOL = 1e-4, 3e-4, 1e-3
#: The paper's continuous numbers (px) and PMD's columns by unit.
PX_TOL = 2e-4
PMD_TOL = {"mm": 3e-4, "µm": 2e-3, "µrad": 0.2}


@pytest.fixture(scope="module")
def oracle():
    with OracleRenderer() as renderer:
        yield renderer


def small(surface: str = "sphere", theta: float = 45.0, size: int = 32, **tables) -> Scene:
    return paper_scene(surface, theta, 4.0, 0.005).with_size(size).updated(**tables)


def station(size: int, **tables) -> Scene:
    """The paper's dent seen by a PMD station of the default coding (tests/test_pmd_measure.py)."""
    return small("flat", 45.0, size, emitter={"kind": "fringes"}).updated(**tables)


# --------------------------------------------------------------------------- the outputs
@pytest.mark.parametrize(
    "tables",
    [
        {},
        {"render": {"supersample": 2}},
        {"camera": {"f_number": 4.0, "aperture_samples": 4}},
        {"render": {"fresnel": "dielectric"}},
        {"render": {"precision": "fp64"}},
    ],
    ids=["pinhole", "supersample", "lens", "fresnel", "fp64"],
)
def test_every_output_is_the_gl_renderers(renderer, oracle, tables):
    scene = small(**tables)
    gl, ours = renderer.render(scene, OUTPUTS), oracle.render(scene, OUTPUTS)
    for name in OUTPUTS:
        a, b = gl.output(name), ours.output(name)
        assert (a.dtype, a.shape) == (b.dtype, b.shape), name
        if a.dtype.kind == "f":
            assert np.array_equal(np.isnan(a), np.isnan(b)), name
    assert np.array_equal(gl.mask, ours.mask) and np.array_equal(gl.rays, ours.rays)
    assert np.abs(gl.image - ours.image).max() < IMAGE_TOL
    seen = gl.mask
    uv_tol = 1e-11 if scene.render.precision == "fp64" else UV_TOL
    assert np.abs(gl.uv - ours.uv)[seen].max() < uv_tol
    hit = np.isfinite(gl.distance)
    assert hit.mean() > 0.5 and np.abs(gl.distance - ours.distance)[hit].max() < DISTANCE_TOL


def test_the_outputs_not_asked_for_are_none_and_out_is_filled(oracle):
    scene = small(size=16)
    frame = oracle.render(scene, ("uv",))
    assert frame.image is None and frame.mask is None and frame.uv.dtype == np.float32
    out = Frame(image=np.empty((16, 16), np.float32), uv=np.empty((16, 16, 2), np.float32))
    filled = oracle.render(scene, ("image", "uv"), out=out)
    assert filled.image is out.image and filled.uv is out.uv
    assert np.array_equal(out.uv, frame.uv, equal_nan=True)
    with pytest.raises(GlshadeError, match=r"out\.image: must be a C-contiguous float32"):
        oracle.render(scene, ("image",), out=Frame(image=np.empty((16, 16))))


def test_the_frames_are_one_trace_shaded_per_frame(renderer, oracle):
    """Each layer is the frame's image traced on its own (to float32 rounding) and the GL
    renderer's stack within one displayed level (the fringes' 256 levels: a sample near a
    step may round to the next one in fp32)."""
    scene = station(24, render={"supersample": 2})
    emitter = scene.active.emitter
    frames = (*emitter.sequence(scene), emitter.white(scene))
    ours = oracle.render(scene, ("frames", "uv"), frames=frames)
    gl = renderer.render(scene, ("frames", "uv"), frames=frames)
    assert ours.frames.dtype == np.float32 and ours.frames.shape == (len(frames), 24, 24)
    alone = np.stack([tracer.trace(emitter.showing(scene, f), "image").image for f in frames])
    assert np.abs(ours.frames - alone).max() < 1e-6
    difference = np.abs(ours.frames - gl.frames)
    assert difference.max() <= emitter.radiance_step(scene) + IMAGE_TOL
    assert (difference > IMAGE_TOL).mean() < 0.01
    with pytest.raises(GlshadeError, match="frames output and a non-empty list"):
        oracle.render(scene, ("frames",))


def test_a_kept_trace_shades_as_a_fresh_one(oracle):
    """The metric's phase sweep is shaded from one trace: the images are a fresh
    renderer's, bit for bit, and another geometry is traced again."""
    scene = small(size=24, render={"supersample": 2})
    assert geometry_key(scene.with_phase(0.7)) == geometry_key(scene)
    assert geometry_key(scene.with_value("defect.dmax", 0.0)) != geometry_key(scene)
    oracle.render(scene)
    for phase in (0.5, 1.25):
        with OracleRenderer() as fresh:
            expected = fresh.render(scene.with_phase(phase), ("image", "uv"))
        got = oracle.render(scene.with_phase(phase), ("image", "uv"))
        assert np.array_equal(got.image, expected.image)
        assert np.array_equal(got.uv, expected.uv, equal_nan=True)


def test_refusals_and_what_it_says_it_is():
    with OracleRenderer(max_pixels=32 * 32) as small_one:
        assert small_one.max_pixels == 1024 and OracleRenderer().max_pixels == DEFAULT_MAX_PIXELS
        assert "NumPy float64 oracle" in small_one.renderer_string
        assert small_one.info().renderer == small_one.renderer_string
        with pytest.raises(
            GlshadeError, match=r"33x32 pixels, more than the NumPy oracle renders \(1024"
        ):
            small_one.render(small(size=32).updated(camera={"width": 33}))
        with pytest.raises(GlshadeError, match="iterations counts the GL renderer"):
            small_one.render(small(size=8), ("image", "iterations"))
    with pytest.raises(GlshadeError, match="memory budget of 1 MiB"):
        OracleRenderer(memory_budget_bytes=1 << 20).render(small(size=8))
    with pytest.raises(GlshadeError, match="max_pixels: must be at least 1"):
        OracleRenderer(max_pixels=0)


def test_the_oracle_renderer_loads_no_gl():
    code = (
        "import sys; from glshade.oracle.renderer import OracleRenderer; "
        "from glshade.scene import paper_scene; "
        "OracleRenderer().render(paper_scene().with_size(8), ('image', 'uv')); "
        "print('moderngl' in sys.modules)"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "False"


# --------------------------------------------------------------------------- the numbers
def assert_same_paper_numbers(gl, ours) -> None:
    assert ours.status == gl.status, (ours.status_reason, gl.status_reason)
    assert ours.visibility_px == gl.visibility_px
    assert ours.visibility_continuous_px == pytest.approx(gl.visibility_continuous_px, abs=PX_TOL)
    assert ours.deflection_px == pytest.approx(gl.deflection_px, abs=PX_TOL)


@pytest.mark.parametrize("surface", ["flat", "cylinder", "sphere"])
@pytest.mark.parametrize("theta", [85.0, 45.0, 5.0])
def test_the_paper_numbers_are_the_gl_renderers(renderer, oracle, surface, theta):
    """The paper's scenes at 64², with stripes the pixels resolve (``period = "auto"``):
    status ok, visibility 1 px everywhere."""
    scene = small(surface, theta, 64, emitter={"period": "auto"})
    gl, ours = measure_scene(renderer, scene), measure_scene(oracle, scene)
    assert gl.status == "ok" and gl.visibility_px >= 1
    assert_same_paper_numbers(gl, ours)


@pytest.mark.parametrize("surface", ["flat", "cylinder", "sphere"])
def test_unresolved_paper_scenes_agree_too(renderer, oracle, surface):
    """The paper's own 2 mm stripes at 96²: unresolved (2.2 px per period) in both, the
    continuous numbers alike."""
    scene = small(surface, 45.0, 96)
    gl, ours = measure_scene(renderer, scene), measure_scene(oracle, scene)
    assert gl.status == "unresolved"
    assert_same_paper_numbers(gl, ours)


def test_a_sensor_records_the_oracles_radiance(renderer, oracle):
    """With a sensor the image is what it records of the radiance, exposed for the
    defect-free scene's brightest point as the GL renderer exposes it; the measured
    numbers are the GL renderer's. (The recorded images themselves are not: a Poisson
    draw takes a varying count of random numbers, so radiances that differ by 1e-5 draw
    different noise from the first pixel whose draw differs on.)"""
    scene = small("flat", 45.0, 48, emitter={"period": "auto"}, defect={"dmax": 0.02})
    scene = scene.updated(sensor=SENSOR)
    gain = oracle.exposure_gain(scene)
    assert gain == pytest.approx(renderer.exposure_gain(scene), rel=1e-5)
    radiance = tracer.trace(scene, "image", develop=False).image
    exposed = scene.with_value("camera.exposure", gain)
    recorded = oracle.render(scene).image
    assert recorded.dtype == np.float32
    assert np.array_equal(recorded, scene.active.develop(exposed, radiance))
    assert not np.array_equal(recorded, oracle.render(scene, exposure=1).image)
    gl, ours = measure_scene(renderer, scene), measure_scene(oracle, scene)
    assert gl.status == "ok" and gl.noise_floor_px is not None
    assert ours.noise_floor_px == gl.noise_floor_px
    assert_same_paper_numbers(gl, ours)
    row_gl, row_ours = Measurement.of(scene, gl).outputs(), Measurement.of(scene, ours).outputs()
    assert row_ours["fold_ratio"] == row_gl["fold_ratio"]


@pytest.mark.parametrize("tables", [{}, {"sensor": SENSOR}], ids=["noiseless", "sensor"])
def test_the_pmd_numbers_are_the_gl_renderers(renderer, oracle, tables, monkeypatch):
    """The oracle's frames measure as the GL renderer's; both recorded by the NumPy
    sensor, so the noise is the same draw (the GPU's record pass draws its own:
    tests/test_gpu_sequence.py)."""
    monkeypatch.setattr("glshade.instruments.pmd.shots.on_gpu", lambda *_: False)
    scene = station(48, **tables)
    gl = PmdMeasurement.of(scene, glshade.measure(scene, renderer=renderer))
    ours = PmdMeasurement.of(scene, glshade.measure(scene, renderer=oracle))
    assert gl.status == "ok" and ours.status == gl.status
    assert ours.unwrap_failures == gl.unwrap_failures == 0
    assert ours.valid_fraction == pytest.approx(gl.valid_fraction, abs=1e-3)
    assert ours.modulation == pytest.approx(gl.modulation, abs=1e-3)
    row_gl, row_ours = gl.outputs(), ours.outputs()
    for column in PmdMeasurement.columns():
        if column.unit in PMD_TOL and row_gl[column.name] is not None:
            tolerance = PMD_TOL[column.unit]
            assert row_ours[column.name] == pytest.approx(row_gl[column.name], abs=tolerance), (
                column.name
            )
        elif column.unit in PMD_TOL:
            assert row_ours[column.name] is None, column.name
