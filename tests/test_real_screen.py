"""A real screen in front of a PMD station: its cover glass, its pixel grid (fill factor,
black matrix), its black level, the room light it reflects and a measured response. Each
part is off by default and leaves no code in the program; each holds its closed form:

- glass: the ray meets the emitting layer ``t (tan i - tan r)`` nearer its foot than the
  same ray continued straight (``sin r = sin i / n``), per pixel within 1e-4 mm;
- pixels: a ray sees the fringe at the centre of the screen pixel it lands in (quantised to
  the screen's levels), the black matrix between them the room light;
- black level and room light: an offset in every frame (the decoded phase keeps none of it);
- a measured response read from a file, as the shader interpolates it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from glshade.components.emitter.fringes.screen import read_response
from glshade.errors import GlshadeError
from glshade.gpu.compose import ShaderFeatures, compose
from glshade.instruments.pmd import decode as pmd
from glshade.oracle.tracer import first_hit
from glshade.scene import Scene, paper_scene


def station(size: int = 48, theta: float = 35.0, **emitter) -> Scene:
    scene = paper_scene("flat", theta_deg=theta, sigma2=4.0, dmax=0.005).with_size(size)
    return scene.updated(emitter={"kind": "fringes", **emitter})


def reflected(scene: Scene) -> np.ndarray:
    """Each pixel's mirror direction (H, W, 3), float64 (the oracle's hits and normals)."""
    origin, directions = scene.active.camera.pixel_rays(scene, None, None, 1)
    shape = directions.shape[:2]
    d = np.asarray(directions, np.float64).reshape(-1, 3)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = np.ascontiguousarray(np.broadcast_to(np.asarray(origin, np.float64), d.shape))
    _, _, n, valid = first_hit(scene, o, d)
    n = n.reshape(-1, 3)
    r = d - 2.0 * np.einsum("nk,nk->n", d, n)[:, None] * n
    r[~valid.reshape(-1)] = np.nan
    return r.reshape(*shape, 3)


@pytest.mark.parametrize("precision", ["fp32", "fp64"])
def test_the_cover_glass_moves_each_point_by_its_closed_form(renderer, precision):
    thickness, index = 1.1, 1.52
    plain = station(theta=30.0).updated(render={"precision": precision})
    glass = plain.updated(emitter={"glass_thickness": thickness, "glass_index": index})
    uv_plain = renderer.render(plain, ("uv",)).uv.astype(np.float64)
    uv_glass = renderer.render(glass, ("uv",)).uv.astype(np.float64)
    r = reflected(plain)
    em_plane = plain.emitter_plane()
    along = np.stack([r @ em_plane.e_u, r @ em_plane.e_v], axis=-1)  # sin i, in the screen
    sin_i = np.linalg.norm(along, axis=-1)
    sin_r = sin_i / index
    tan_i = sin_i / np.sqrt(1.0 - sin_i**2)
    tan_r = sin_r / np.sqrt(1.0 - sin_r**2)
    expected = -(thickness * (tan_i - tan_r) / sin_i)[..., None] * along
    seen = np.isfinite(uv_plain).all(axis=-1) & np.isfinite(uv_glass).all(axis=-1)
    assert seen.sum() > 1000
    moved = (uv_glass - uv_plain)[seen]
    assert np.abs(moved - expected[seen]).max() <= 1e-4
    assert np.linalg.norm(moved, axis=-1).max() > 0.04  # the glass really moves them
    # and the float64 oracle refracts alike
    oracle = glass.active.emitter.coordinates(
        glass, np.zeros((1, 3)), r[24:25, 24].reshape(1, 3) * 1.0
    )
    assert np.isfinite(oracle[0]).all()


def test_a_ray_sees_the_fringe_at_its_screen_pixels_centre(renderer):
    scene = station(size=64, pixel_pitch=0.5, fill_factor=0.64, ambient=0.03, levels=64)
    image = renderer.render(scene, ("image",)).image
    uv = renderer.render(scene, ("uv",)).uv.astype(np.float64)
    seen = np.isfinite(uv).all(axis=-1)
    expected = scene.emitter.radiance_uv(uv[..., 0], uv[..., 1])
    # a ray within 1e-4 mm of a pixel's or its lit square's edge may fall either side
    pitch, lit = 0.5, 0.5 * math.sqrt(0.64) * 0.5
    s = uv + np.asarray(scene.emitter.half_size)
    offset = np.abs(s - (np.floor(s / pitch) + 0.5) * pitch)
    clear = seen & np.all(np.abs(offset - lit) > 1e-4, axis=-1)
    clear &= np.all(np.abs(offset - 0.5 * pitch) > 1e-4, axis=-1)
    assert clear.sum() > 3000
    np.testing.assert_allclose(image[clear], expected[clear], atol=2e-6)
    dark = clear & np.any(offset > lit, axis=-1)
    assert np.all(image[dark] == pytest.approx(0.03))  # the black matrix: the room light
    assert 0.55 < 1.0 - dark.sum() / clear.sum() < 0.75  # about the fill factor is lit


def test_a_pixelated_screen_under_a_lobe_is_averaged_over_its_kernel(renderer):
    """No closed form there: the kernel's lattice over the pixels; each layer is still the
    frame rendered alone, and a lobe much wider than a pixel sees the pixels' average."""
    scene = station(size=24, pixel_pitch=0.05, fill_factor=0.5, levels=0).updated(
        render={"reflection": "beckmann", "roughness": 1e-3}
    )
    frames = scene.active.emitter.sequence(scene)[:4]
    stack = renderer.render(scene, ("frames",), frames=frames).frames
    alone = renderer.render(scene.active.emitter.showing(scene, frames[2]), ("image",)).image
    np.testing.assert_array_equal(stack[2], alone)
    continuous = scene.updated(emitter={"pixel_pitch": 0.0})
    smooth = renderer.render(continuous.active.emitter.showing(continuous, frames[2])).image
    # the lobe (about 0.36 mm on the screen) spans seven 0.05 mm pixels: half their area lit
    np.testing.assert_allclose(alone, 0.5 * smooth, atol=0.03)


def test_black_level_and_room_light_are_an_offset_the_decoding_drops(renderer):
    plain = station(size=40, levels=0)
    dim = plain.updated(emitter={"black_level": 0.002, "ambient": 0.05})
    frames = plain.active.emitter.sequence(plain)
    a = renderer.render(plain, ("frames",), frames=frames).frames.astype(np.float64)
    b = renderer.render(dim, ("frames",), frames=frames).frames.astype(np.float64)
    seen = a[0] > 0
    np.testing.assert_allclose(b[:, seen], 0.052 + 0.998 * a[:, seen], atol=2e-6)
    periods, shifts = len(plain.emitter.periods), plain.emitter.shifts
    coding = plain.emitter.codec
    count = periods * shifts
    one = pmd.decode(a[:count].reshape(periods, shifts, 40, 40), coding, direction="v")
    two = pmd.decode(b[:count].reshape(periods, shifts, 40, 40), coding, direction="v")
    both = one.valid & two.valid
    assert both.sum() > 500
    np.testing.assert_allclose(two.s_mm[both], one.s_mm[both], atol=2e-4)


def test_a_measured_response_is_read_and_shown(renderer, tmp_path):
    commanded = np.arange(256)
    luminance = 0.35 + 250.0 * (commanded / 255.0) ** 2.4
    curve = tmp_path / "screen.csv"
    curve.write_text(
        "# commanded, cd/m2\n"
        + "".join(f"{c}\t{v:.6f}\n" for c, v in zip(commanded, luminance, strict=True))
    )
    scene = station(size=40, response_file=str(curve), frame_shift_index=1)
    image = renderer.render(scene, ("image",)).image
    uv = renderer.render(scene, ("uv",)).uv.astype(np.float64)
    seen = np.isfinite(uv).all(axis=-1)
    expected = scene.emitter.radiance_uv(uv[..., 0], uv[..., 1])
    assert np.abs(image[seen] - expected[seen]).max() <= 1e-5 + scene.active.emitter.radiance_step(
        scene
    )
    # the response is the measured curve's, normalised: (L - L(0)) / (L(255) - L(0))
    response = read_response(str(curve))
    assert response(np.array([0.5]))[0] == pytest.approx(0.5**2.4, rel=1e-3)
    gamma = station(size=40, gamma=2.4, frame_shift_index=1)
    np.testing.assert_allclose(image, renderer.render(gamma, ("image",)).image, atol=2e-3)


def test_bad_response_files_are_one_line(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("0, 1\n128, x\n255, 200\n")
    with pytest.raises(GlshadeError, match="line 2 of .*bad.csv is"):
        station(response_file=str(bad))
    bad.write_text("10, 1\n255, 200\n")
    with pytest.raises(GlshadeError, match="increase from 0"):
        station(response_file=str(bad))
    bad.write_text("0, 5\n255, 5\n")
    with pytest.raises(GlshadeError, match="displays more than its 0"):
        station(response_file=str(bad))
    with pytest.raises(GlshadeError, match="does not exist"):
        station(response_file=str(tmp_path / "missing.csv"))
    good = tmp_path / "good.csv"
    good.write_text("0 0\n1 1\n")
    with pytest.raises(GlshadeError, match="emitter.gamma"):
        station(response_file=str(good), gamma=2.2)
    with pytest.raises(GlshadeError, match="emitter.pixel_pitch"):
        station(pixel_pitch=400.0)


def test_each_part_is_off_by_default_and_leaves_no_code():
    plain = compose(ShaderFeatures.from_scene(station(), ("image",)))[1]
    for marker in ("u_emitter_glass", "u_emitter_pixel", "t_emitter_response"):
        assert marker not in plain
    real = station(glass_thickness=1.0, pixel_pitch=0.25)
    source = compose(ShaderFeatures.from_scene(real, ("image",)))[1]
    assert "u_emitter_glass_thickness" in source and "u_emitter_pixel_pitch" in source
    # the defaults: no glass, a continuous screen, no black level, no room light, a gamma
    em = station().emitter
    assert (em.glass_thickness, em.pixel_pitch, em.black_level, em.ambient) == (0, 0, 0, 0)
    assert em.response_file is None
