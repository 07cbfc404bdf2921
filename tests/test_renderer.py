"""Renderer behaviour: outputs, determinism, memory, budget, closed forms, Blinn-Phong limits."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest

from glshade.errors import GlshadeError, SceneError
from glshade.frame import Frame
from glshade.gpu.context import GLContext
from glshade.gpu.renderer import Renderer
from glshade.scene import paper_scene


def test_only_requested_outputs_are_computed_and_read(renderer):
    scene = paper_scene().with_size(32)
    frame = renderer.render(scene, ("uv",))
    assert frame.image is None and frame.mask is None
    assert frame.uv.shape == (32, 32, 2) and frame.uv.dtype == np.float32
    assert len(renderer._targets[(32, 32, ("uv",), False, 0)].textures) == 1
    full = renderer.render(scene, ("image", "uv", "mask"))
    assert full.image.dtype == np.float32 and full.mask.dtype == np.bool_
    np.testing.assert_array_equal(full.uv, frame.uv)
    # mask and NaN agree
    np.testing.assert_array_equal(full.mask, ~np.isnan(full.uv[..., 0]))


def test_fp64_uv_is_float64(renderer):
    frame = renderer.render(
        paper_scene().with_size(16).updated(render={"precision": "fp64"}), ("uv", "mask")
    )
    assert frame.uv.dtype == np.float64
    np.testing.assert_array_equal(np.isnan(frame.uv[..., 0]), ~frame.mask)


def test_same_scene_gives_identical_bytes(renderer):
    scene = paper_scene("sphere", 25.0, 1.0, 0.005).with_size(64)
    a = renderer.render(scene, ("image", "uv", "mask"))
    renderer.render(paper_scene("cylinder").with_size(48))  # something in between
    b = renderer.render(scene, ("image", "uv", "mask"))
    assert a.image.tobytes() == b.image.tobytes()
    assert a.uv.tobytes() == b.uv.tobytes()
    assert a.mask.tobytes() == b.mask.tobytes()


def test_the_wait_for_a_trace_releases_the_interpreter_lock(renderer, monkeypatch):
    """moderngl keeps the interpreter lock in every call, so its finish would stop the
    engine's analysis threads for a whole trace: the renderer waits through glFinish called
    with ctypes (which releases the lock), from the loader moderngl took its functions
    from; the frame is the one moderngl's own finish gives."""
    import ctypes

    from glshade.gpu.context import released_finish

    finish = released_finish(renderer.context.gl)
    assert isinstance(finish, ctypes._CFuncPtr)
    assert not type(finish)._flags_ & ctypes._FUNCFLAG_PYTHONAPI  # which would keep the lock
    scene = paper_scene("sphere", 25.0, 1.0, 0.005).with_size(64)
    released = renderer.render(scene, ("uv",)).output("uv")
    monkeypatch.setattr(renderer.context, "wait", renderer.context.gl.finish)
    np.testing.assert_array_equal(renderer.render(scene, ("uv",)).output("uv"), released)


def test_render_into_preallocated_arrays(renderer):
    scene = paper_scene().with_size(16)
    out = Frame(image=np.zeros((16, 16), np.float32))
    frame = renderer.render(scene, ("image",), out=out)
    assert frame.image is out.image and out.image.max() > 0.9
    with pytest.raises(GlshadeError, match="out.image"):
        renderer.render(scene, ("image",), out=Frame(image=np.zeros((8, 8), np.float32)))


def _rss_bytes() -> int:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


@pytest.mark.skipif(
    not os.path.exists("/proc/self/statm"), reason="needs /proc to read the resident set size"
)
def test_thousands_of_frames_do_not_grow_memory(renderer):
    scenes = [paper_scene(s).with_size(24) for s in ("flat", "cylinder", "sphere")]
    for scene in scenes * 20:  # warm-up: programs, targets, allocator pools
        renderer.render(scene, ("image", "uv", "mask"))
    before = _rss_bytes()
    for i in range(3000):
        renderer.render(scenes[i % 3].with_phase(0.001 * i), ("image", "uv", "mask"))
    grown = _rss_bytes() - before
    assert grown < 16 * 2**20, f"resident memory grew by {grown / 2**20:.1f} MiB over 3000 frames"


def test_memory_budget_is_enforced(gl_context):
    with Renderer(gl_context, memory_budget_bytes=1 << 20) as small:
        small.render(paper_scene().with_size(64))  # 64² x 8 B: fits
        with pytest.raises(SceneError) as info:
            small.render(paper_scene().with_size(1024), ("image", "uv"))
    assert info.value.field == "camera.width x camera.height"
    assert "memory budget of 1 MiB" in str(info.value)


def test_release_twice_is_harmless(gl_context):
    r = Renderer(gl_context)
    r.render(paper_scene().with_size(8))
    r.release()
    r.release()
    with GLContext() as own:
        pass
    own.release()


def test_flat_small_slope_closed_form():
    """Max |Δv| on a flat mirror tends to 2 De (dmax/σ) e^(-1/2) (SPEC §6), nearly
    independent of θ."""
    expected = 2 * 256.0 * (0.005 / 1.0) * math.exp(-0.5)
    with Renderer() as r:
        # 1024 px: at grazing views a coarser grid steps over the slope's peak (256 px
        # at 15 deg: 0.54 mm per pixel along z, 4% low).
        for theta in (85.0, 45.0, 15.0, 5.0):
            scene = paper_scene("flat", theta, 1.0, 0.005).with_size(1024)
            v1 = r.render(scene, ("uv",)).uv[..., 1]
            v0 = r.render(scene.without_defect(), ("uv",)).uv[..., 1]
            shift = np.nanmax(np.abs(v1 - v0))
            assert shift == pytest.approx(expected, rel=0.02), theta


def test_blinn_phong_converges_to_mirror(renderer):
    scene = paper_scene("flat", 45.0, 4.0, 0.005).with_size(64)
    mirror = renderer.render(scene).image
    errors = []
    for n in (1e5, 1e7, 1e9, 1e11):
        phong = renderer.render(
            scene.updated(render={"reflection": "blinn-phong", "shininess": n})
        ).image
        errors.append(float(np.abs(phong - mirror).max()))
    assert errors == sorted(errors, reverse=True)
    assert errors[0] > 0.05  # a broad lobe really blurs the stripes
    assert errors[-1] < 1e-4
    # the lobe's blur falls as 1/n: two decades of n, two decades of error
    assert errors[1] / errors[2] == pytest.approx(100, rel=0.2)


def test_blinn_phong_keeps_a_uniform_emitter_uniform(renderer):
    """Stripes far wider than their period make a uniform emitter: the normalised lobe
    must return it unchanged, however broad."""
    scene = (
        paper_scene("sphere", 30.0, 4.0, 0.005)
        .with_size(48)
        .updated(emitter={"stripe_sigma": 200.0})
    )
    mirror = renderer.render(scene, ("image", "mask"))
    phong = renderer.render(scene.updated(render={"reflection": "blinn-phong", "shininess": 1e3}))
    level = 200.0 * math.sqrt(2 * math.pi) / 10.0  # Poisson sum of unit-peak stripes
    np.testing.assert_allclose(mirror.image[mirror.mask], level, rtol=1e-5)
    np.testing.assert_allclose(phong.image[mirror.mask], level, rtol=1e-5)


def test_supersampling_averages_sub_pixels(renderer):
    """ss = 2 equals the mean of the four sub-pixel images of a camera twice as fine."""
    scene = paper_scene("flat", 45.0, 1.0, 0.005).with_size(32)
    coarse = renderer.render(scene.updated(render={"supersample": 2})).image
    fine = renderer.render(scene.with_size(64)).image
    pooled = fine.reshape(32, 2, 32, 2).mean(axis=(1, 3))
    np.testing.assert_allclose(coarse, pooled, atol=2e-6)


def test_auto_exposure_of_a_supersampled_sensor_scene(renderer):
    """ "auto" exposes a supersampled scene from its own rays (its draws count them)."""
    scene = (
        paper_scene()
        .with_size(32)
        .updated(render={"supersample": 2}, sensor={"full_well_e": 1e6, "read_noise_e": 0.0})
    )
    image = renderer.render(scene, ("image",)).output("image")
    assert 0.85 < float(image.max()) < 0.95  # the brightest stripe at 0.9 of full scale
