"""The ``frames`` output: a fringe sequence shaded from one trace, one image-array layer per
frame. Each layer equals the scene rendered alone with that frame shown (the same rays, the
same shading: bit for bit on llvmpipe; a driver may order the arithmetic of a one-pattern
program otherwise, and NVIDIA's H200 differs by the last bit, so the tests allow it),
through supersampling, draws split by the loop limit, Fresnel and sequences longer than one
draw; the float64 tracer agrees within a grey level; only the code a program needs is
composed."""

from __future__ import annotations

import numpy as np
import pytest

from glshade.errors import GlshadeError
from glshade.gpu.compose import ShaderFeatures, compose
from glshade.gpu.renderer import MAX_FRAMES_PER_DRAW, Renderer
from glshade.oracle import tracer
from glshade.scene import Scene, paper_scene


def fringes(size: int = 48, **emitter) -> Scene:
    scene = paper_scene("flat", theta_deg=40.0, sigma2=4.0, dmax=0.02).with_size(size)
    return scene.updated(emitter={"kind": "fringes", **emitter})


def same(actual: np.ndarray, expected: np.ndarray) -> None:
    """Equal but for float32's last bit (one unit in the last place)."""
    np.testing.assert_allclose(actual, expected, rtol=1.2e-7, atol=0.0)


def alone(renderer, scene: Scene, frame) -> np.ndarray:
    """Frame ``frame`` rendered as the scene's only image."""
    shown = scene.active.emitter.showing(scene, frame)
    return renderer.render(shown, ("image",)).output("image")


def test_every_layer_is_the_frame_rendered_alone(renderer):
    scene = fringes()
    frames = (*scene.active.emitter.sequence(scene), scene.active.emitter.white(scene))
    stack = renderer.render(scene, ("frames", "uv", "mask"), frames=frames)
    assert stack.frames.shape == (33, 48, 48) and stack.frames.dtype == np.float32
    for index in (0, 5, 13, 22, 31, 32):
        same(stack.frames[index], alone(renderer, scene, frames[index]))
    # the other outputs are those of a plain render; the white frame is 1 where seen
    plain = renderer.render(scene, ("uv", "mask"))
    np.testing.assert_array_equal(stack.uv, plain.uv)
    np.testing.assert_array_equal(stack.frames[-1], np.where(plain.mask, 1.0, 0.0))


def test_supersampled_and_split_draws_add_up_alike(renderer):
    scene = fringes(size=32).updated(render={"supersample": 3})
    frames = scene.active.emitter.sequence(scene)[:12]
    whole = renderer.render(scene, ("frames",), frames=frames).frames
    for index in (0, 7, 11):
        same(whole[index], alone(renderer, scene, frames[index]))
    split = Renderer(renderer.context, loop_budget=150)  # a few rays a draw
    try:
        parts = split.render(scene, ("frames", "rays"), frames=frames)
    finally:
        split.release()
    assert np.all(parts.rays == 9)
    np.testing.assert_allclose(parts.frames, whole, atol=1e-6)


def test_a_sequence_longer_than_a_draw_is_chunked(renderer):
    scene = fringes(size=24, shifts=12)  # 2 x 4 x 12 = 96 frames
    frames = scene.active.emitter.sequence(scene)
    assert len(frames) > MAX_FRAMES_PER_DRAW
    stack = renderer.render(scene, ("frames",), frames=frames).frames
    for index in (0, MAX_FRAMES_PER_DRAW - 1, MAX_FRAMES_PER_DRAW, len(frames) - 1):
        same(stack[index], alone(renderer, scene, frames[index]))


def test_fresnel_weighs_every_frame(renderer):
    scene = fringes(size=32).updated(render={"fresnel": "conductor", "extinction": 3.0})
    frames = scene.active.emitter.sequence(scene)[:4]
    stack = renderer.render(scene, ("frames",), frames=frames).frames
    same(stack[2], alone(renderer, scene, frames[2]))
    assert 0.3 < np.nanmax(stack) < 1.0  # a reflectance below 1 scales the fringes


@pytest.mark.parametrize("precision", ["fp32", "fp64"])
def test_layers_agree_with_the_float64_tracer(renderer, precision):
    scene = fringes(size=32, gamma=2.2).updated(render={"precision": precision})
    frames = scene.active.emitter.sequence(scene)
    stack = renderer.render(scene, ("frames", "mask"), frames=frames).frames
    for index in (1, 18):
        oracle = tracer.trace(scene.active.emitter.showing(scene, frames[index]), ("image",))
        error = np.abs(stack[index] - oracle.image)
        step = scene.active.emitter.radiance_step(scene)  # one grey level at a level's edge
        assert error.max() <= 2e-3 + step
        assert (error > 2e-3).sum() <= 3


def test_the_stack_is_radiance_never_developed(renderer):
    scene = fringes(size=32).updated(sensor={"full_well_e": 100.0})
    frames = scene.active.emitter.sequence(scene)[:2]
    stack = renderer.render(scene, ("frames",), frames=frames).frames
    noiseless = fringes(size=32)
    same(stack[1], alone(renderer, noiseless, frames[1]))


def test_only_the_needed_code_is_composed():
    scene = fringes()
    frames_only = compose(ShaderFeatures.from_scene(scene, ("frames",), 4))[1]
    image_only = compose(ShaderFeatures.from_scene(scene, ("image",)))[1]
    assert "out_frames" in frames_only and "const int PATTERNS = 4;" in frames_only
    assert "uniform vec4 u_emitter_frame[PATTERNS];" in frames_only
    assert "const int PATTERNS = 1;" in image_only and "out_frames" not in image_only
    # one shading path: the image and the stack call the same reflection model
    assert "void shade(" in frames_only and "void shade(" in image_only
    uv_only = compose(ShaderFeatures.from_scene(scene, ("uv",)))[1]
    assert "u_emitter_frame" not in uv_only and "float pattern_sums" not in uv_only
    assert "emitter_radiance(" not in uv_only
    stripes = compose(ShaderFeatures.from_scene(paper_scene(), ("image",)))[1]
    assert "fringe" not in stripes and "u_emitter_frame" not in stripes


def test_a_stack_needs_a_sequence_emitter_and_its_frames(renderer):
    with pytest.raises(GlshadeError, match='emitter.kind = "stripes" shows one pattern'):
        compose(ShaderFeatures.from_scene(paper_scene(), ("frames",), 2))
    scene = fringes(size=16)
    with pytest.raises(GlshadeError, match="frames output and a non-empty list"):
        renderer.render(scene, ("frames",))
    with pytest.raises(GlshadeError, match="frames output and a non-empty list"):
        renderer.render(scene, ("image",), frames=scene.active.emitter.sequence(scene))
    with pytest.raises(GlshadeError, match="the image and the frames outputs are two programs"):
        compose(ShaderFeatures.from_scene(scene, ("image", "frames"), 2))
