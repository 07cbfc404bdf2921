"""One shading path for images and frame stacks: every reflection model (the mirror,
Blinn-Phong, Beckmann and GGX in every lobe method, eq. (1)'s coherent/diffuse split,
Fresnel) shades every pattern an emitter shows, the fringe frames of a PMD stack as the
stripes.

- each layer of a stack is the image rendered with that frame shown, to float32's last bit;
- the image agrees with the float64 oracle (brute-force lobe integrals, Monte-Carlo for
  the microfacets, a fine quadrature of the Lambert integral) within each method's stated
  error, for the stripes and for fringes along v and along u;
- the modulation a lobe leaves of a fringe is the closed form of
  :mod:`glshade.oracle.lobe` (``exp(-2π² s²/P²)``, GGX's ``k K1(k)``), exactly for the
  closed-form lobes and within 5 % for the lattice where it keeps more than 0.2.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from glshade.components.emitter.fringes.table import FringeFrame
from glshade.oracle import tracer
from glshade.oracle.lobe import kernel_transfer, lobe_footprint
from glshade.scene import Scene, paper_scene

#: The reflection models and methods, each with the largest difference from the float64
#: oracle it may show (of the emitter's peak): the mirror's are rounding; Blinn-Phong's
#: closed form is paraxial (measured 7e-4); the microfacets' oracle is Monte-Carlo with
#: 16384 samples a pixel (standard error about 3e-3) and their closed form linear in the
#: slopes (measured 6e-3, the sampled lattice 1.2e-2).
MODELS = {
    "mirror": ({}, 1e-4),
    "eq1-mirror": ({"height_rms_um": 0.04}, 1e-4),
    "fresnel": ({"fresnel": "dielectric"}, 1e-4),
    "blinn-phong": ({"reflection": "blinn-phong", "shininess": 2e6}, 2e-3),
    "beckmann": ({"reflection": "beckmann", "roughness": 7e-4}, 1.2e-2),
    "beckmann-lattice": (
        {
            "reflection": "beckmann",
            "roughness": 7e-4,
            "lobe_method": "lattice",
            "lobe_samples": 256,
        },
        1.2e-2,
    ),
    "ggx": ({"reflection": "ggx", "roughness": 5e-4}, 1.2e-2),
    "ggx-sampling": (
        {"reflection": "ggx", "roughness": 5e-4, "lobe_method": "sampling", "lobe_samples": 256},
        2e-2,
    ),
    "ggx-eq1-conductor": (
        {"reflection": "ggx", "roughness": 5e-4, "height_rms_um": 0.04, "fresnel": "conductor"},
        1.2e-2,
    ),
}
#: The emitters: the stripes, and fringes of a 4 mm finest period along v and along u (a
#: coarse one too: eq. (1)'s diffuse part then varies across the screen).
EMITTERS = {
    "stripes": {},
    "fringes-v": {"kind": "fringes", "periods": (4.0, 32.0, 400.0), "frame_shift_index": 1},
    "fringes-u": {
        "kind": "fringes",
        "periods": (4.0, 32.0, 400.0),
        "frame_direction": "u",
        "frame_shift_index": 3,
    },
    "fringes-coarse-u": {
        "kind": "fringes",
        "periods": (4.0, 32.0, 400.0),
        "frame_direction": "u",
        "frame_period_index": 2,
    },
}


def scene_of(model: str, emitter: str, size: int = 16) -> Scene:
    base = paper_scene("flat", theta_deg=40.0, sigma2=4.0, dmax=0.005).with_size(size)
    return base.updated(emitter=EMITTERS[emitter], render=MODELS[model][0])


@pytest.mark.parametrize("model", MODELS)
def test_each_layer_is_the_frame_rendered_alone_for_every_model(renderer, model):
    scene = scene_of(model, "fringes-v", size=20)
    emitter = scene.active.emitter
    sequence = emitter.sequence(scene)
    frames = (
        sequence[0],
        sequence[5],
        sequence[11],
        sequence[14],
        sequence[-1],
        emitter.white(scene),
    )
    stack = renderer.render(scene, ("frames",), frames=frames).frames
    assert np.ptp(stack[0]) > 0.2 * stack[0].max()  # the fringes are there
    for index, frame in enumerate(frames):
        alone = renderer.render(emitter.showing(scene, frame), ("image",)).image
        # the same code on the same rays: equal, but for the last bit where the compiler
        # orders a program of one pattern's arithmetic otherwise than one of six
        np.testing.assert_allclose(stack[index], alone, rtol=2.4e-7, atol=1e-12)


@pytest.mark.parametrize("emitter", EMITTERS)
@pytest.mark.parametrize("model", MODELS)
def test_every_model_agrees_with_the_float64_oracle(renderer, model, emitter):
    scene = scene_of(model, emitter)
    window = (slice(4, 12), slice(4, 12))
    shader = renderer.render(scene, ("image", "mask"))
    oracle = tracer.trace(scene, ("image", "mask"), rows=window[0], cols=window[1])
    both = shader.mask[window] & oracle.mask
    assert both.sum() > 40
    error = np.abs(shader.image[window] - oracle.image)[both]
    step = scene.active.emitter.radiance_step(scene)  # a grey level's edge
    assert error.max() <= MODELS[model][1] + step, f"{model} x {emitter}: {error.max():.3g}"
    assert np.ptp(oracle.image[both]) > 0.1 * oracle.image[both].max()  # a pattern to disagree


def modulation_shares(renderer, scene: Scene, direction: str, period: float) -> np.ndarray:
    """Each pixel's modulation of a 4-step fringe of ``period`` along ``direction`` over
    the displayed fringe's fundamental times its response to the screen's white."""
    em = scene.emitter
    steps = 2.0 * np.pi * np.arange(4) / 4
    frames = [
        FringeFrame(direction, 0, n, period, float(steps[n]), em.offset, em.amplitude)
        for n in range(4)
    ]
    stack = renderer.render(scene, ("frames",), frames=(*frames, em.white()))
    layers = stack.frames.astype(np.float64)
    sine = np.tensordot(np.sin(steps), layers[:4], 1)
    cosine = np.tensordot(np.cos(steps), layers[:4], 1)
    fundamental = em.harmonics(frames[0])[1]
    return 0.5 * np.hypot(sine, cosine) / (fundamental * layers[4])


#: Finishes whose lobes keep from about 0.3 to 0.96 of a 2 or 4 mm fringe at 256 mm.
FINISHES = {
    "blinn-phong": {"reflection": "blinn-phong", "shininess": 2e6},
    "blinn-phong-wide": {"reflection": "blinn-phong", "shininess": 4e5},
    "beckmann": {"reflection": "beckmann", "roughness": 1e-3},
    "beckmann-lattice": {
        "reflection": "beckmann",
        "roughness": 1e-3,
        "lobe_method": "lattice",
        "lobe_samples": 256,
    },
    "ggx": {"reflection": "ggx", "roughness": 1e-3},
    "ggx-lattice": {
        "reflection": "ggx",
        "roughness": 1e-3,
        "lobe_method": "lattice",
        "lobe_samples": 256,
    },
}


@pytest.mark.parametrize("finish", FINISHES)
def test_the_modulation_a_finish_leaves_is_its_closed_form(renderer, finish):
    scene = (
        paper_scene("flat", theta_deg=45.0)
        .without_defect()
        .with_size(24)
        .updated(emitter={"kind": "fringes", "levels": 0}, render=FINISHES[finish])
    )
    footprint = lobe_footprint(scene)
    assert footprint is not None
    lattice = "lattice" in finish
    compared, kept = 0, []
    for direction, axis in (("v", 1), ("u", 0)):
        for period in (2.0, 4.0):
            shares = modulation_shares(renderer, scene, direction, period)
            closed = footprint.modulation(axis, period)
            readable = closed > 0.2
            error = np.abs(shares[readable] / closed[readable] - 1.0)
            assert error.size == 0 or error.max() <= (0.05 if lattice else 1e-5), (
                direction,
                period,
                error.max(),
            )
            compared += int(readable.sum())
            kept.append(float(np.median(closed)))
    assert compared > 400
    assert min(kept) < 0.6 and max(kept) > 0.3  # the lobe takes a readable share away


def test_the_kernels_transfer_functions():
    """exp(-k²/2) and k K1(k): 1 at 0, the Gaussian's e^-1/2 at 1, GGX's known values."""
    k = np.array([0.0, 1.0, 2.0, 5.0])
    np.testing.assert_allclose(kernel_transfer("gaussian", k), np.exp(-0.5 * k**2))
    # K1(1) = 0.601907, K1(2) = 0.139866, K1(5) = 0.004045 (Abramowitz & Stegun, table 9.8)
    np.testing.assert_allclose(
        kernel_transfer("ggx", k), [1.0, 0.601907, 2 * 0.139866, 5 * 0.0040446], rtol=2e-5
    )
    # the GLSL lattice's GGX and Gaussian kernels have these transfers: a million points of
    # the same inverse CDFs in NumPy
    rng = np.random.default_rng(3)
    u1, u2 = rng.random(1 << 20), rng.random(1 << 20)
    for kernel, radius in (
        ("gaussian", np.sqrt(-2.0 * np.log1p(-u1))),
        ("ggx", np.sqrt(u1 / (1.0 - u1))),
    ):
        x = radius * np.cos(2.0 * math.pi * u2)
        for frequency in (0.5, 1.5):
            assert np.mean(np.cos(frequency * x)) == pytest.approx(
                float(kernel_transfer(kernel, np.array(frequency))), abs=3e-3
            )


def test_a_station_reads_a_finish_by_its_closed_form_or_names_it():
    """The silent mirror, gone: a PMD station on a glossy part reports the modulation the
    finish leaves (its closed form), and a finish that washes the finest fringe out is
    unresolved, named."""
    from glshade.instruments.pmd.station import measure_pmd
    from glshade.metrics.status import dent_window

    station = paper_scene("flat", theta_deg=45.0).with_size(64)
    station = station.updated(emitter={"kind": "fringes", "directions": ("v",), "levels": 0})
    gloss = station.updated(render={"reflection": "beckmann", "roughness": 1e-3})
    record = measure_pmd(gloss)
    window = dent_window(gloss, (64, 64))
    footprint = lobe_footprint(gloss)
    assert footprint is not None
    closed = float(np.median(footprint.modulation(1, 2.0)[window]))
    assert record.status == "ok" and record.modulation == pytest.approx(closed, rel=0.05)
    assert closed < 0.6  # the finish really takes half the fringe
    rough = station.updated(
        render={"reflection": "ggx", "roughness": 0.02, "lobe_method": "lattice"}
    )
    washed = measure_pmd(rough)
    assert washed.status == "unresolved"
    assert "the finish (ggx, roughness 0.02) spreads each screen point" in washed.status_reason
