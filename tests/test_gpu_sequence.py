"""A frame stack recorded and decoded on the GPU (glshade.gpu.sequence): the counter-based
generator against its published answers, the record pass's noise against the sensor's law
and its NumPy reference, and the decode pass against the NumPy decoder (one codec; float64
finish), whatever region the passes cover."""

from __future__ import annotations

import math

import numpy as np
import pytest

from glshade.components.registry import registry
from glshade.frame import Region
from glshade.gpu.compose import render_template
from glshade.instruments.pmd.capture import decode_sequence
from glshade.instruments.pmd.model import station_model
from glshade.instruments.pmd.settings import PmdSettings
from glshade.instruments.pmd.shots import finished, plan_of, shoot
from glshade.scene import paper_scene

# Random123's known answers for Philox4x32-10 (kat_vectors): counter, key, output.
PHILOX_KAT = [
    ((0, 0, 0, 0), (0, 0), (0x6627E8D5, 0xE169C58D, 0xBC57AC4C, 0x9B00DBD8)),
    (
        (0xFFFFFFFF,) * 4,
        (0xFFFFFFFF, 0xFFFFFFFF),
        (0x408F276D, 0x41C83B0E, 0xA20BC7C6, 0x6D5451FD),
    ),
    (
        (0x243F6A88, 0x85A308D3, 0x13198A2E, 0x03707344),
        (0xA4093822, 0x299F31D0),
        (0xD16CFE09, 0x94FDCCEB, 0x5001E420, 0x24126EA1),
    ),
]


def test_philox_gives_random123s_known_answers(renderer):
    source = (
        "#version 450\nlayout(local_size_x = 1) in;\n"
        "layout(std430, binding = 0) buffer Io { uvec4 data[]; };\n"
        + render_template("lib/philox.glsl")
        + "void main() { uint i = gl_GlobalInvocationID.x;\n"
        "  data[3u * i + 2u] = philox4x32_10(data[3u * i], data[3u * i + 1u].xy); }\n"
    )
    words = np.zeros((len(PHILOX_KAT), 3, 4), np.uint32)
    for index, (counter, key, _) in enumerate(PHILOX_KAT):
        words[index, 0], words[index, 1, :2] = counter, key
    with renderer.context.current() as ctx:
        program = ctx.compute_shader(source)
        buffer = ctx.buffer(words.tobytes())
        buffer.bind_to_storage_buffer(0)
        program.run(len(PHILOX_KAT))
        ctx.memory_barrier()
        out = np.frombuffer(buffer.read(), np.uint32).reshape(words.shape)
        buffer.release()
        program.release()
    for index, (_, _, expected) in enumerate(PHILOX_KAT):
        assert tuple(int(w) for w in out[index, 2]) == expected


# --------------------------------------------------------------------------- record
SIDE = 256


def sensor_scene(**sensor):
    values = {"full_well_e": 10000.0, "read_noise_e": 5.0, "bit_depth": 16, "seed": 3, **sensor}
    return paper_scene().with_size(SIDE).updated(camera={"exposure": 1.0}, sensor=values)


def gpu_recorded(renderer, scene, levels, recording=0, region=None):
    """Frames of uniform radiance ``levels`` (one each) as the record pass records them."""
    passes = renderer.sequence_passes()
    radiance = np.stack([np.full((SIDE, SIDE), level, np.float32) for level in levels])
    stack = passes.upload(radiance, (SIDE, SIDE))
    sensor = scene.active.sensor
    keys = sensor.frame_keys(scene, [f"frame {i}" for i in range(len(levels))], recording)
    recorded = passes.record(
        stack, sensor, sensor.record_glsl(scene), sensor.record_uniforms(scene, 1.0), keys, region
    )
    return passes.read(recorded, region).astype(np.float64)


def electrons(scene, recorded):
    sensor = scene.sensor
    return (recorded - sensor.black_level) / (1.0 - sensor.black_level) * sensor.full_well_e


@pytest.mark.parametrize(
    ("full_well", "level"),
    [
        (1000.0, 0.002),  # 2 e-: Poisson by inversion
        (1000.0, 0.05),  # 50 e-: transformed rejection (PTRS)
        (1000.0, 0.6),  # 600 e-: PTRS
        (10000.0, 0.3),  # 3000 e-: PTRS
        (1e6, 0.5),  # 5e5 e-
        (1e9, 0.5),  # 5e8 e-: the acceptance test's terms of order one in float32
    ],
)
def test_the_record_pass_has_the_sensors_mean_and_variance(renderer, full_well, level):
    """Uniform radiance recorded on the GPU: the electrons' mean is the exposure's, their
    variance the photon noise plus the read noise plus the quantisation's (65 536 frames
    of pixels: the variance within 4 % and 5 of its standard errors), as NumPy's develop
    of the same frame."""
    scene = sensor_scene(full_well_e=full_well)
    read = scene.sensor.read_noise_e
    e = electrons(scene, gpu_recorded(renderer, scene, [level])[0])
    mean = level * full_well
    step = full_well / ((1.0 - scene.sensor.black_level) * scene.sensor.full_scale_dn)
    variance = mean + read**2 + step**2 / 12.0
    assert e.mean() == pytest.approx(mean, abs=5.0 * math.sqrt(variance / e.size) + 1e-3)
    assert e.var() == pytest.approx(variance, rel=0.04)
    developed = (
        registry().active(scene).sensor.develop(scene, np.full((SIDE, SIDE), level, np.float32))
    )
    reference = electrons(scene, developed.astype(np.float64))
    assert e.var() == pytest.approx(reference.var(), rel=0.05)


def test_few_electrons_are_poisson_distributed(renderer):
    """At 2 e- and no read noise the recorded counts are Poisson's: P(k) = e^-2 2^k / k!
    for k = 0 … 6, each within 5 standard errors."""
    scene = sensor_scene(full_well_e=1000.0, read_noise_e=0.0)
    counts = np.rint(electrons(scene, gpu_recorded(renderer, scene, [0.002])[0]))
    for k in range(7):
        expected = math.exp(-2.0) * 2.0**k / math.factorial(k)
        found = float((counts == k).mean())
        assert found == pytest.approx(expected, abs=5.0 * math.sqrt(expected / counts.size))


def test_recording_clips_at_full_scale_and_keeps_the_black_level(renderer):
    scene = sensor_scene(bit_depth=12)
    bright, dark = gpu_recorded(renderer, scene, [1.5, 0.0])
    assert (bright == 1.0).all()
    black = scene.sensor.black_level
    assert dark.mean() == pytest.approx(black, abs=5e-6)
    assert dark.std() == pytest.approx((1 - black) * 5.0 / 1e4, rel=0.05)
    assert (dark > 0).all()  # the black level keeps the read noise off 0


def test_the_noise_is_the_seeds_the_frames_and_the_recordings(renderer):
    """The same seed, scene, frame and recording record the same values, whatever region
    the pass covers; another recording, frame or seed records others."""
    scene = sensor_scene()
    first = gpu_recorded(renderer, scene, [0.3, 0.3])
    again = gpu_recorded(renderer, scene, [0.3, 0.3])
    assert np.array_equal(first, again)
    assert not np.array_equal(first[0], first[1])  # two frames, two noises
    other = gpu_recorded(renderer, scene, [0.3, 0.3], recording=1)
    assert (other != first).mean() > 0.9
    seeded = gpu_recorded(renderer, sensor_scene(seed=4), [0.3, 0.3])
    assert (seeded != first).mean() > 0.9
    region = Region(37, 101, 50, 61)
    part = gpu_recorded(renderer, scene, [0.3, 0.3], region=region)
    assert np.array_equal(part, first[:, region.rows_slice, region.cols_slice])


# --------------------------------------------------------------------------- decode
def station(surface="flat", size=96, **emitter):
    scene = paper_scene(surface, 45.0, 4.0, 0.005).with_size(size)
    periods = [2.0, 16.0, 128.0, 1024.0] if surface == "flat" else [10.0, 80.0, 640.0]
    return scene.updated(emitter={"kind": "fringes", "periods": periods, **emitter})


DECODED = [
    ("flat", {}),
    ("sphere", {}),
    ("flat", {"directions": ["v"], "shifts": 3}),
    ("sphere", {"periods": [400.0], "directions": ["u"]}),  # one period: the coarsest rule
    ("flat", {"shifts": 8}),
]


@pytest.mark.parametrize(("surface", "emitter"), DECODED)
def test_the_gpu_decodes_as_numpy_does(renderer, surface, emitter):
    """The same noiseless sequence shot both ways: the decoded screen points within 1e-6
    mm of NumPy's, the same pixels valid and unwrapped onto the same fringes, the
    modulation and offset maps the same to float32's rounding."""
    scene = station(surface, **emitter)
    coding = station_model(scene).coding
    reference = shoot(renderer, scene, coding, PmdSettings(), gpu=False)
    gpu = shoot(renderer, scene, coding, PmdSettings(), gpu=True)
    a, b = reference.decoding, gpu.decoding
    assert a.valid.any() and np.array_equal(a.valid, b.valid)
    assert np.array_equal(np.isnan(a.uv), np.isnan(b.uv))
    assert np.nanmax(np.abs(a.uv - b.uv)) < 1e-6
    for mine, theirs in ((a.modulation, b.modulation), (a.offset, b.offset)):
        np.testing.assert_allclose(theirs, mine, rtol=2e-7, atol=0)  # float32's rounding
    assert np.nanmax(np.abs(reference.share - gpu.share)) < 1e-6
    assert np.array_equal(reference.uv, gpu.uv, equal_nan=True)


def test_the_gpu_decodes_recorded_frames_as_numpy_does(renderer):
    """Noisy frames recorded once, decoded by both: within 1e-6 mm, the same validity
    and the same fringes (the unwrapping), on every pixel of both paths' valid ones."""
    scene = station("sphere").updated(sensor={"full_well_e": 3000.0})
    model = station_model(scene)
    coding = model.coding
    shot = shoot(renderer, scene, coding, PmdSettings(), gpu=False, keep_frames=True)
    recorded, seen = shot.recorded, np.all(np.isfinite(shot.uv), axis=-1)
    reference = decode_sequence(coding, recorded, shot.peak_response, PmdSettings(), seen)
    passes = renderer.sequence_passes()
    stack = passes.upload(recorded, recorded.shape[1:])
    maps = passes.decode(stack, plan_of(coding, reference.threshold))
    gpu = finished(coding, maps, reference.threshold, seen)
    assert reference.valid.mean() > 0.3 and np.array_equal(reference.valid, gpu.valid)
    assert np.nanmax(np.abs(reference.uv - gpu.uv)) < 1e-6


def test_a_region_decodes_as_the_whole_image_does(renderer):
    scene = station("sphere").updated(sensor={"full_well_e": 10000.0})
    coding = station_model(scene).coding
    whole = shoot(renderer, scene, coding, PmdSettings(), gpu=True)
    region = Region(20, 31, 40, 33)
    part = shoot(
        renderer, scene, coding, PmdSettings(), gpu=True, region=region, peak=whole.peak_response
    )
    cut = region.slices
    assert np.array_equal(part.decoding.uv, whole.decoding.uv[cut], equal_nan=True)
    assert np.array_equal(part.decoding.valid, whole.decoding.valid[cut])
    assert np.array_equal(part.first, whole.first[cut])
    assert np.array_equal(part.share, whole.share[:, cut[0], cut[1]], equal_nan=True)


def test_a_region_renders_as_the_whole_image_does(renderer):
    """``render(..., region=)`` traces the region alone: its uv map and frames are the
    whole image's cut to it, with 2 x 2 rays a pixel too."""
    scene = station("sphere", 64).updated(render={"supersample": 2})
    emitter = scene.active.emitter
    frames = (*emitter.sequence(scene)[:6], emitter.white(scene))
    whole = renderer.render(scene, ("frames", "uv"), frames=frames)
    region = Region(9, 14, 30, 21)
    part = renderer.render(scene, ("frames", "uv"), frames=frames, region=region)
    rows, cols = region.slices
    assert part.output("uv").shape == (30, 21, 2)
    assert np.array_equal(part.output("uv"), whole.output("uv")[rows, cols], equal_nan=True)
    assert np.array_equal(
        part.output("frames"), whole.output("frames")[:, rows, cols], equal_nan=True
    )


def test_a_long_or_summed_stack_is_sent_back_and_decodes_alike(renderer, gl_context):
    """More frames than one draw shades (73), or a pixel's rays summed over several
    draws (a small loop budget): the stack is read, summed and sent back to the GPU, and
    decodes as NumPy decodes it."""
    from glshade.gpu.renderer import MAX_FRAMES_PER_DRAW, Renderer

    periods = list(np.geomspace(2.0, 1024.0, 9))
    scene = station("flat", 48, periods=periods)
    assert 2 * 9 * 4 + 1 > MAX_FRAMES_PER_DRAW
    coding = station_model(scene).coding
    long_ref = shoot(renderer, scene, coding, PmdSettings(), gpu=False).decoding
    long_gpu = shoot(renderer, scene, coding, PmdSettings(), gpu=True).decoding
    assert np.array_equal(long_ref.valid, long_gpu.valid) and long_ref.valid.any()
    assert np.nanmax(np.abs(long_ref.uv - long_gpu.uv)) < 1e-6
    summed = station("sphere", 48).updated(render={"supersample": 3})
    coding = station_model(summed).coding
    with Renderer(gl_context, loop_budget=200) as small:
        ref = shoot(small, summed, coding, PmdSettings(), gpu=False).decoding
        gpu = shoot(small, summed, coding, PmdSettings(), gpu=True).decoding
    assert np.array_equal(ref.valid, gpu.valid) and ref.valid.any()
    assert np.nanmax(np.abs(ref.uv - gpu.uv)) < 1e-6
