"""Every ray of a pixel is traced and counted, however many there are.

llvmpipe stops a fragment's loops after 65535 iterations of all its loops together; a
pixel of supersample 16 x 1024 aperture samples traces 262144 rays. The renderer splits
each pixel's samples over draws that stay within a loop budget and sums them, and the
``rays`` output counts what each pixel summed. Checked here:

- the count is supersample² x aperture samples at settings far beyond the limit (a lens,
  a dent's root solve, a microfacet lattice);
- the flat mirror at f/22 keeps its brightness at 16 x 1024 rays per pixel (one draw
  returned 25 % of it, 6 % with the paper's dent), and its image equals the 4 x 64 one
  within that setting's quadrature error;
- a frame split over many draws is the frame of one draw (every output), and the float64
  oracle's mean over the same rays.
"""

from __future__ import annotations

import numpy as np
import pytest

from glshade.gpu.renderer import Renderer, pixel_samples, samples_per_draw
from glshade.oracle import tracer
from glshade.scene import Scene, paper_scene

ALL = ("image", "uv", "mask", "distance", "iterations", "rays")


def crop(scene: Scene, width: int, height: int) -> Scene:
    """The centre ``width`` x ``height`` pixels of ``scene``'s sensor (same pitch)."""
    return scene.updated(camera={"width": width, "height": height})


def flat_lens(
    width: int = 16, height: int = 12, supersample: int = 16, samples: int = 1024, dent=False
):
    """The flat mirror at f/22 (focused on the surface), pixels of the 256² camera;
    ``dent``: with the paper's dent (σ² 4, 5 µm) at the centre."""
    scene = paper_scene("flat", 45.0, 4.0, 0.005).with_size(256)
    scene = scene if dent else scene.without_defect()
    return crop(scene, width, height).updated(
        camera={"f_number": 22.0, "aperture_samples": samples}, render={"supersample": supersample}
    )


@pytest.mark.parametrize("dent, width, height", [(False, 16, 12), (True, 8, 6)])
def test_the_flat_mirror_at_f22_keeps_its_brightness(renderer, dent, width, height):
    """16 x 1024 rays per pixel against 4 x 64 (which one draw traces whole): the same
    integral, the blur of the stripes over the lens disc and the pixel, so the images
    agree to the coarse setting's quadrature error: its 64-point Vogel spiral and 4 x 4
    sub-pixel grid leave about 1e-3 here (9.6e-4 and 9.7e-4 at most over these crops of
    radiance 0.39…0.68), the mean 2e-6 and 7e-6. 2e-3 per pixel and 1e-4 on the mean keep
    a margin of 2 and 14. One draw of all 262144 rays returned 25 % of the brightness, 6 %
    with the dent (whose solve loops about 3 times per ray)."""
    big = renderer.render(flat_lens(width, height, dent=dent), ("image", "rays"))
    small = renderer.render(flat_lens(width, height, 4, 64, dent), ("image", "rays"))
    assert (big.rays == 16 * 16 * 1024).all()
    assert (small.rays == 4 * 4 * 64).all()
    assert big.image.mean() == pytest.approx(small.image.mean(), abs=1e-4)
    assert np.abs(big.image - small.image).max() < 2e-3


@pytest.mark.parametrize(
    "name, scene",
    [
        (
            "sphere dent, supersample 12 x 1024",
            crop(paper_scene("sphere", 45.0, 1.0, 0.005).with_size(256), 8, 6).updated(
                camera={"f_number": 22.0, "aperture_samples": 1024}, render={"supersample": 12}
            ),
        ),
        (
            "cylinder dent at 15 deg, supersample 16 x 256",
            crop(paper_scene("cylinder", 15.0, 1.0, 0.005).with_size(256), 8, 6).updated(
                camera={"f_number": 22.0, "aperture_samples": 256}, render={"supersample": 16}
            ),
        ),
        (
            "Beckmann lattice of 256 samples, supersample 4 x 64",
            flat_lens(8, 6, 4, 64).updated(
                render={
                    "reflection": "beckmann",
                    "roughness": 0.01,
                    "lobe_method": "lattice",
                    "lobe_samples": 256,
                }
            ),
        ),
    ],
)
def test_every_pixel_sums_all_its_rays(renderer, name, scene):
    """Far beyond the loop limit in one draw (a dent's march and polish, a lattice's
    slope samples per ray), every pixel still sums supersample² x aperture samples rays;
    the draws are more than one and each within the budget."""
    per_ray = scene.active.loop_iterations(scene, renderer.root_solver)
    assert pixel_samples(scene) * per_ray > 65535
    assert samples_per_draw(scene, renderer.root_solver) * per_ray <= renderer.loop_budget
    frame = renderer.render(scene, ("image", "rays", "mask"))
    assert (frame.rays == pixel_samples(scene)).all(), name
    assert frame.mask.all()


def test_many_draws_are_one_draw(gl_context, renderer):
    """A dented frame of 4 x 64 rays per pixel traced in one draw and in 342 draws (341
    slices of 3 samples and one of 1): every output agrees to float32 rounding of the
    sums (the image, uv and distance are means; iterations the most; the mask and counts
    exact)."""
    scene = crop(paper_scene("sphere", 30.0, 1.0, 0.005).with_size(256), 12, 8).updated(
        camera={"f_number": 8.0, "aperture_samples": 64, "focus_distance": 300.0},
        render={"supersample": 4},
    )
    one = renderer.render(scene, ALL)
    per_ray = scene.active.loop_iterations(scene, renderer.root_solver)
    with Renderer(gl_context, loop_budget=per_ray * 15 // 4) as split:
        assert samples_per_draw(scene, split.root_solver, split.loop_budget) == 3
        many = split.render(scene, ALL)
    assert (one.rays == 1024).all() and (many.rays == 1024).all()
    assert (one.mask == many.mask).all()
    assert np.abs(one.image - many.image).max() < 1e-6
    assert np.nanmax(np.abs(one.uv - many.uv)) < 1e-5
    assert np.nanmax(np.abs(one.distance - many.distance)) < 1e-4
    assert (one.iterations == many.iterations).all()


def test_split_draws_are_the_oracles_mean_of_the_same_rays(gl_context):
    """Against the float64 oracle's mean over the same rays (sub-pixel positions and
    Vogel aperture points): a frame of 2 x 16 rays per pixel in 22 draws of 3 (the last
    of 1), and a pixel of 8 x 1024 rays (65536: past the limit in one draw). The
    tolerances are the single-draw fp32 shader's against the oracle
    (tests/test_optics.py)."""
    scene = (
        paper_scene("flat", 30.0, 2.0, 0.005)
        .with_size(24)
        .updated(
            camera={"f_number": 8.0, "aperture_samples": 16, "focus_distance": 300.0},
            render={"supersample": 2},
        )
    )
    with Renderer(gl_context, loop_budget=3) as split:
        shader = split.render(scene, ("image", "uv", "mask", "rays"))
    oracle = tracer.trace(scene, ("image", "uv", "mask"))
    assert (shader.rays == 64).all()
    assert (shader.mask == oracle.mask).all()
    assert np.abs(shader.image - oracle.image).max() < 2e-3
    assert np.nanmax(np.abs(shader.uv - oracle.uv)) < 5e-4

    big = crop(scene, 4, 2).updated(camera={"aperture_samples": 1024}, render={"supersample": 8})
    with Renderer(gl_context) as renderer:
        frame = renderer.render(big, ("image", "uv", "rays"))
    rows, cols = slice(1, 2), slice(2, 3)
    window = tracer.trace(big, ("image", "uv"), rows=rows, cols=cols)
    assert (frame.rays == 65536).all()
    assert np.abs(frame.image[rows, cols] - window.image).max() < 2e-3
    assert np.abs(frame.uv[rows, cols] - window.uv).max() < 5e-4


def test_a_draw_the_limit_cut_short_is_traced_again_in_halves(gl_context, renderer):
    """With no loop budget at all (every ray in one draw), llvmpipe's limiter cuts the
    draw: its ``rays`` count falls short, the renderer traces it again in halves until
    each draw holds, and the frame is the budgeted one. (A GPU without a limit traces it
    in one draw: the same frame.)"""
    scene = flat_lens(4, 3)
    budgeted = renderer.render(scene, ("image", "rays"))
    with Renderer(gl_context, loop_budget=1 << 40) as unbudgeted:
        assert samples_per_draw(scene, unbudgeted.root_solver, unbudgeted.loop_budget) == 262144
        frame = unbudgeted.render(scene, ("image", "rays"))
    assert (frame.rays == 262144).all()
    assert np.abs(frame.image - budgeted.image).max() < 1e-5
