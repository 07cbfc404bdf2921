"""The dent's region of influence: the metric computed there gives the whole frame's numbers.

Two oracles: the full-frame analysis (``Baseline(..., full_frame=True)``) on the same maps,
and, for the region itself, the binary images of every phase computed over the whole frame
(no pixel outside the region's box may differ). The scenes are the awkward ones: a dent at
the image's edge, off centre, under a fold, on a height map, seen through a lens.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as hs

from glshade.instruments.stripes.single import (
    emitter_map,
    judged,
    levels_from_image,
    phase_images,
    shades_from_map,
)
from glshade.metrics import contours as ct
from glshade.metrics import visibility as vis
from glshade.metrics.region import SEARCHED_PX
from glshade.scene import Scene, paper_scene

SIZE = 192


def both_ways(renderer, scene: Scene) -> tuple[vis.Visibility, vis.Visibility, vis.Baseline]:
    """The scene measured over the whole frame and in its dent's region, from one trace."""
    normal = scene.without_defect()
    v0, v1 = emitter_map(renderer, normal), emitter_map(renderer, scene)
    settings_ = vis.MetricSettings()
    pattern = scene.active.emitter.pattern(scene)
    mapped = shades_from_map(scene)
    normal_images = None if mapped else phase_images(renderer, normal)
    defect_images = None if mapped else phase_images(renderer, scene)
    levels = levels_from_image(scene, settings_)
    found = []
    for full_frame in (True, False):
        baseline = vis.Baseline(v0, pattern, settings_, normal_images, levels, full_frame)
        found.append(judged(scene, baseline, v1, baseline.measure(v1, defect_images)))
    return found[0], found[1], baseline


def assert_same(full: vis.Visibility, region: vis.Visibility) -> None:
    assert vis.differing_fields(full, region) == []
    moved = dataclasses.replace(region, islands=region.islands + 1, stripe_contrast=math.nan)
    assert vis.differing_fields(full, moved) == ["islands"] + (
        [] if math.isnan(full.stripe_contrast) else ["stripe_contrast"]
    )
    searched = region.displacement_px > 0
    np.testing.assert_array_equal(full.displacement_px[searched], region.displacement_px[searched])
    elsewhere = np.isfinite(full.displacement_px) & ~searched
    assert np.all(full.displacement_px[elsewhere] <= SEARCHED_PX)


def half_field_mm(scene: Scene) -> float:
    """Half the image's width on a flat plate seen from above (mm)."""
    cam = scene.camera
    return 0.5 * cam.width * cam.pixel_pitch * cam.distance / cam.focal


SCENES = {
    "centred": lambda: paper_scene("flat", 45.0, 4.0, 0.005),
    "off centre": lambda: paper_scene("flat", 45.0, 1.0, 0.005).with_value("defect.x0", 1.5),
    "at the image's edge": lambda: paper_scene("flat", 85.0, 1.0, 0.005).with_values(
        [
            ("defect.z0", 0.95 * half_field_mm(paper_scene("flat", 85.0))),
            ("defect.x0", 0.45 * half_field_mm(paper_scene("flat", 85.0))),
        ]
    ),
    "under a fold": lambda: paper_scene("flat", 5.0, 1.0, 0.005),
    "sphere": lambda: paper_scene("sphere", 45.0, 4.0, 0.005),
    "cylinder, grazing": lambda: paper_scene("cylinder", 5.0, 16.0, 0.003),
    "through a lens": lambda: paper_scene("flat", 45.0, 4.0, 0.005).updated(
        camera={"f_number": 8.0, "aperture_samples": 4}
    ),
}


@pytest.mark.parametrize("name", list(SCENES))
def test_the_region_gives_the_whole_frames_numbers(renderer, name):
    full, region, _ = both_ways(renderer, SCENES[name]().with_size(SIZE))
    assert full.visibility_px > 0  # contours moved: the region path decides
    assert_same(full, region)


def test_a_dent_on_a_height_map(renderer, tmp_path):
    """A measured surface: a height map of a gently curved part, the dent on it."""
    x = np.arange(-30.0, 30.0 + 1e-9, 0.25)
    xx, zz = np.meshgrid(x, x)
    np.save(tmp_path / "part.npy", 0.002 * xx**2 / 2.0 + 0.001 * zz)
    scene = paper_scene("flat", 35.0, 4.0, 0.005).updated(
        surface={"kind": "heightmap", "file": str(tmp_path / "part.npy"), "spacing": (0.25, 0.25)}
    )
    full, region, _ = both_ways(renderer, scene.with_size(SIZE))
    assert full.visibility_px > 0
    assert_same(full, region)


def test_no_binary_pixel_differs_outside_the_region(renderer):
    """At every phase, every pixel where the two binary images differ lies in the region's
    box: it never cuts off a moved contour."""
    scene = paper_scene("cylinder", 25.0, 4.0, 0.005).with_size(SIZE)
    v0 = emitter_map(renderer, scene.without_defect())
    v1 = emitter_map(renderer, scene)
    baseline = vis.Baseline(v0, scene.active.emitter.pattern(scene), vis.MetricSettings())
    box = baseline.influence(v1).box
    assert box is not None
    inside = np.zeros(baseline.valid.shape, bool)
    inside[box] = True
    for phase in baseline.phases:
        differs = baseline.binary(v0, float(phase)) != baseline.binary(v1, float(phase))
        assert differs.any() and not (differs & ~inside).any()
    # the box is the dent's, not the whole image
    assert inside.mean() < 0.6


# ------------------------------------------------------------------ the comparison alone
@hs.composite
def patched_pairs(draw) -> tuple[np.ndarray, np.ndarray, np.ndarray, ct.Patch]:
    """A striped binary image (wavy, broken, part of it unseen), and the same image with a
    box rewritten: random pixels or the stripes moved by a few rows there."""
    seed = draw(hs.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    height, width = draw(hs.integers(8, 48)), draw(hs.integers(8, 48))
    rows = np.arange(height)[:, None] + rng.uniform(0, 5) * np.sin(
        np.arange(width)[None, :] / rng.uniform(2, 20)
    )
    normal = ((rows / rng.uniform(3, 12)) % 1) < rng.uniform(0.2, 0.7)
    if draw(hs.booleans()):
        normal &= rng.random((height, width)) > 0.05
    valid = np.ones((height, width), bool)
    if draw(hs.booleans()):
        valid[: rng.integers(0, 5)] = False
    normal &= valid
    r0 = draw(hs.integers(0, height - 1))
    r1 = draw(hs.integers(r0 + 1, height))
    c0 = draw(hs.integers(0, width - 1))
    c1 = draw(hs.integers(c0 + 1, width))
    defect = normal.copy()
    if draw(hs.booleans()):
        defect[r0:r1, c0:c1] = rng.random((r1 - r0, c1 - c0)) < 0.5
    else:
        defect[r0:r1, c0:c1] = np.roll(normal, draw(hs.integers(-3, 3)), axis=0)[r0:r1, c0:c1]
    defect &= valid
    return normal, defect, valid, ct.Patch(slice(r0, r1), slice(c0, c1), defect[r0:r1, c0:c1])


@settings(max_examples=300, deadline=None)
@given(patched_pairs())
def test_the_patched_comparison_is_the_whole_ones(case):
    """Around the patch, the comparison finds what the whole image's does: the same
    distance at the same place, islands, unpaired stripes and pairs (None where the whole
    image's largest distance is 0: the whole image decides where a 0 lies)."""
    normal_binary, defect, valid, patch = case
    edge = ct.border_pixels(valid)
    normal = ct.find_stripes(normal_binary, edge)
    whole = ct.compare(normal, defect, edge, 0.25)
    around = ct.compare_patched(normal, patch, edge, 0.25)
    if whole.distance_px == 0:
        assert around is None
    else:
        assert around == whole
