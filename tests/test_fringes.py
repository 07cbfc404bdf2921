"""The fringe emitter: its table (defaults, one-line refusals, TOML), the exact
quantisation and gamma, GPU against the float64 oracle frame by frame, no code of one
emitter in the other's program, and the command line (render works, the stripe metric
refuses, phase measuring is the default)."""

from __future__ import annotations

import json
import math

import cv2
import numpy as np
import pytest

from glshade.app.cli import main
from glshade.components.emitter.fringes import NO_STRIPE_METRIC
from glshade.components.emitter.fringes.codec import FringeCodec
from glshade.errors import GlshadeError, SceneError
from glshade.files import read_png
from glshade.gpu.compose import ShaderFeatures, compose
from glshade.oracle import tracer
from glshade.scene import Scene, paper_scene


def fringes(**values) -> Scene:
    return paper_scene("flat", theta_deg=45.0).updated(emitter={"kind": "fringes", **values})


# --------------------------------------------------------------------------- the table
def test_defaults_and_the_stripes_stay_the_default():
    assert paper_scene().emitter.kind == "stripes"
    em = fringes().emitter
    assert em.periods == (2.0, 16.0, 128.0, 1024.0)
    assert (em.shifts, em.directions, em.offset, em.amplitude) == (4, ("v", "u"), 0.5, 0.5)
    assert (em.gamma, em.levels) == (1.0, 256)
    assert (em.frame_direction, em.frame_period_index, em.frame_shift_index) == ("v", 0, 0)
    assert em.distance == 256.0 and em.half_size == (150.0, 150.0)


@pytest.mark.parametrize(
    ("values", "words"),
    [
        ({"shifts": 2}, ["emitter.shifts", "2"]),
        ({"periods": [2.0, 16.0, 8.0, 1024.0]}, ["emitter.periods", "increasing", "8"]),
        ({"periods": [2.0, 16.0, 128.0, 256.0]}, ["emitter.periods", "300 mm", "256"]),
        ({"gamma": 0.0}, ["emitter.gamma", "0"]),
        ({"gamma": -1.0}, ["emitter.gamma", "-1"]),
        ({"levels": 1}, ["emitter.levels", "1"]),
        ({"offset": 0.6}, ["emitter.offset", "offset + amplitude <= 1", "0.6"]),
        ({"frame_period_index": 4}, ["emitter.frame_period_index", "4"]),
        ({"frame_shift_index": 4}, ["emitter.frame_shift_index", "4"]),
        ({"directions": ["v", "w"]}, ["emitter.directions", "w"]),
    ],
)
def test_refusals_are_one_line_naming_the_value(values, words):
    with pytest.raises(SceneError) as info:
        fringes(**values)
    text = str(info.value)
    assert "\n" not in text
    for word in words:
        assert word in text, text


def test_the_frame_shown_need_not_be_one_the_sequence_codes():
    # a sequence of u alone keeps the default frame (v): setting the directions is enough
    assert fringes(directions=["u"]).emitter.frame_direction == "v"


def test_the_coarsest_period_is_checked_along_each_listed_direction():
    wide = {"half_size": [600.0, 150.0]}
    with pytest.raises(SceneError, match="along 'u'.*1200 mm"):
        fringes(**wide)
    assert fringes(directions=["v"], **wide).emitter.directions == ("v",)


def test_toml_round_trip(tmp_path):
    scene = fringes(
        periods=[3.0, 24.0, 400.0], shifts=5, directions=["u"], frame_direction="u",
        frame_period_index=2, frame_shift_index=3, gamma=2.2, levels=0, offset=0.4,
        amplitude=0.3,
    )  # fmt: skip
    path = tmp_path / "fringes.toml"
    scene.save(path)
    assert Scene.load(path) == scene
    text = path.read_text()
    assert 'kind = "fringes"' in text and "periods = [" in text
    # a stripes scene keeps writing the stripes' parameters only
    assert "periods" not in paper_scene().to_dict()["emitter"]


# --------------------------------------------------------------------------- the radiance
def test_quantisation_and_gamma_on_known_values():
    em = fringes(levels=5, gamma=2.0, frame_period_index=1).emitter  # P = 16 mm
    # s = v + 150: v = -150 is s = 0 (cos 1), v = -146 is a quarter period (cos 0), ...
    v = np.array([-150.0, -146.0, -142.0, -150.0 + 16.0 / 3.0])
    commanded = 0.5 + 0.5 * np.cos(2.0 * math.pi * (v + 150.0) / 16.0)
    assert commanded == pytest.approx([1.0, 0.5, 0.0, 0.25])
    # 5 levels: 0, 0.25, 0.5, 0.75, 1 (0.25 is a level; halves round up), then squared
    assert em.fringe_radiance(v) == pytest.approx([1.0, 0.25, 0.0, 0.0625])
    five = FringeCodec(levels=5).displayed(np.array([0.125, 0.12499, 0.3, 1.2, -0.1]))
    assert five == pytest.approx([0.25, 0.0, 0.25, 1.0, 0.0])
    root = FringeCodec(levels=0, gamma=0.5).displayed(np.array([0.3]))
    assert root == pytest.approx([math.sqrt(0.3)])
    # the phase step: frame n shows the pattern shifted by n/N of a period
    shifted = fringes(frame_shift_index=1, levels=0).emitter
    assert shifted.fringe_radiance(np.array([-150.0 + 0.5]))[0] == pytest.approx(1.0)
    # u frames vary along u from its edge
    crossed = fringes(frame_direction="u", levels=0, half_size=[100.0, 150.0]).emitter
    assert crossed.fringe_radiance(np.array([-100.0, -99.0]))[0:2] == pytest.approx([1.0, 0.0])


def small(scene: Scene) -> Scene:
    """32 x 24 pixels over the paper's field of view (rows cropped)."""
    return scene.with_size(32).updated(camera={"height": 24})


def _compare(renderer, scene: Scene, precision: str = "fp32") -> None:
    scene = scene.updated(render={"precision": precision})
    shader = renderer.render(scene, ("image", "uv", "mask"))
    oracle = tracer.trace(scene, ("image", "uv", "mask"))
    both = shader.mask & oracle.mask
    inner = cv2.erode(both.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    assert (shader.mask != oracle.mask).sum() <= 2
    assert inner.sum() > 200
    tol = {"fp32": 2e-3, "fp64": 1e-5}[precision]
    error = np.abs(shader.image - oracle.image)[inner]
    step = scene.active.emitter.radiance_step(scene)
    assert error.max() <= tol + step
    # a level apart only where a ray lands on a level's edge: a few pixels at most
    assert (error > tol).sum() <= max(2, inner.sum() // 50)
    assert oracle.image[inner].max() - oracle.image[inner].min() > 0.5  # fringes are seen


@pytest.mark.parametrize("direction", ["v", "u"])
@pytest.mark.parametrize("shift", [0, 3])
def test_gpu_agrees_with_the_oracle_per_frame(renderer, direction, shift):
    scene = fringes(frame_direction=direction, frame_shift_index=shift, frame_period_index=1)
    _compare(renderer, small(scene))


def test_gpu_agrees_with_the_oracle_on_a_dented_plate_in_fp64(renderer):
    scene = paper_scene("flat", theta_deg=45.0, sigma2=9.0, dmax=0.05).updated(
        emitter={"kind": "fringes", "gamma": 2.2, "frame_shift_index": 2}
    )
    scene = small(scene)
    _compare(renderer, scene, "fp32")
    _compare(renderer, scene, "fp64")


def test_each_emitters_code_is_absent_from_the_others_program():
    stripes_src = compose(ShaderFeatures.from_scene(paper_scene(), ("image",)))[1]
    fringes_src = compose(ShaderFeatures.from_scene(fringes(), ("image",)))[1]
    assert "u_emitter_frame_period" in fringes_src and "float stripes(" not in fringes_src
    assert "u_emitter_sigma" not in fringes_src
    assert "float stripes(" in stripes_src and "u_emitter_fringe" not in stripes_src
    for source in (stripes_src, fringes_src):
        assert "bool emitter_hit(" in source


def test_the_stripe_metric_refuses_fringes():
    with pytest.raises(GlshadeError) as info:
        fringes().active.emitter.pattern(fringes())
    assert str(info.value) == NO_STRIPE_METRIC


# --------------------------------------------------------------------------- the command
def test_render_and_measure_from_a_scene_file(tmp_path, capsys):
    scene = fringes(frame_direction="u", frame_shift_index=1, frame_period_index=1).updated(
        camera={"width": 40, "height": 30}
    )
    path, out = tmp_path / "fringes.toml", tmp_path / "frame.png"
    scene.save(path)
    assert main(["render", str(path), "-o", str(out)]) == 0
    image = read_png(out)
    assert image.shape[:2] == (30, 40) and image.max() > image.min()
    capsys.readouterr()
    # the paper's metric measures the stripes on the same screen, as phase measuring shows
    # its fringes on a scene of stripes
    assert main(["measure", str(path), "--method", "paper", "--json"]) == 0
    assert "visibility_px" in json.loads(capsys.readouterr().out)
    # without --method, a scene of fringes is measured as a phase-measuring station does
    assert main(["measure", str(path), "--json"]) == 0
    assert "pmd_shift_mm" in capsys.readouterr().out


def test_a_stripes_scene_is_not_held_to_the_fringes_checks():
    wide = paper_scene().updated(emitter={"half_size": [1e4, 1e4]})
    assert wide.emitter.kind == "stripes"
    with pytest.raises(SceneError, match="20000 mm"):
        wide.updated(emitter={"kind": "fringes"})
