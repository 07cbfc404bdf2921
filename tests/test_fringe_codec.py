"""The fringe codec: one coding for the screen, the station and the frames manifest. It is
the one validation (a table value it refuses is refused with its message, naming the scene
key; a table makes its codec once and the decoder never checks it again), an amplitude
above the offset is shown but not decoded, the manifest's coding reads back as the codec,
and its NumPy formula is what the shader renders, to float32's rounding."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from glshade.components.emitter.fringes import codec as codec_module
from glshade.components.emitter.fringes.codec import FringeCodec
from glshade.errors import GlshadeError, SceneError
from glshade.instruments.pmd import decode as pmd
from glshade.instruments.pmd.capture import decode_sequence
from glshade.instruments.pmd.model import station_model
from glshade.instruments.pmd.settings import PmdSettings, check_scene
from glshade.scene import Scene, paper_scene

#: One unit in the last place of a float32 in [1, 2).
ULP = 2.0**-24


def fringes(size: int = 48, **emitter) -> Scene:
    scene = paper_scene("flat", theta_deg=45.0).with_size(size)
    return scene.updated(emitter={"kind": "fringes", **emitter})


# --------------------------------------------------------------------------- the rules
@pytest.mark.parametrize(
    ("table", "codec", "key"),
    [
        ({"shifts": 2}, {"shifts": 2}, "emitter.shifts"),
        ({"periods": [2, 16, 8, 1024]}, {"periods_mm": (2, 16, 8, 1024)}, "emitter.periods"),
        ({"periods": [2.0, 16.0, 128.0]}, {"periods_mm": (2.0, 16.0, 128.0)}, "emitter.periods"),
        ({"periods": [2.0, 1e9]}, {"periods_mm": (2.0, 1e9)}, "emitter.periods"),
        ({"half_size": [600.0, 150.0]}, {"screen_half_size_mm": (600.0, 150.0)}, "emitter.periods"),
        ({"gamma": 0.0}, {"gamma": 0.0}, "emitter.gamma"),
        ({"levels": 1}, {"levels": 1}, "emitter.levels"),
        ({"offset": 0.6}, {"offset": 0.6}, "emitter.offset"),
        ({"amplitude": 0.7}, {"amplitude": 0.7}, "emitter.offset"),
        ({"directions": ["v", "w"]}, {"directions": ("v", "w")}, "emitter.directions"),
        ({"black_level": 0.6}, {"screen_black_level": 0.6}, "emitter.black_level"),
    ],
)  # fmt: skip
def test_a_value_the_codec_refuses_is_refused_by_the_table_with_its_message(table, codec, key):
    with pytest.raises(SceneError) as from_codec:
        FringeCodec(**codec)
    with pytest.raises(SceneError) as from_table:
        fringes(**table)
    assert str(from_table.value) == str(from_codec.value)
    assert str(from_codec.value).startswith(f"{key}: must be ")
    assert "\n" not in str(from_codec.value)


def test_a_measured_response_beside_a_gamma_is_one_rule(tmp_path):
    curve = tmp_path / "screen.csv"
    curve.write_text("0 0\n128 0.2\n255 1\n")
    with pytest.raises(SceneError, match="^emitter.gamma: must be 1 where") as from_codec:
        FringeCodec(gamma=2.2, screen_response_file=str(curve))
    with pytest.raises(SceneError) as from_table:
        fringes(gamma=2.2, response_file=str(curve))
    assert str(from_table.value) == str(from_codec.value)


def test_a_table_makes_its_codec_once_and_the_decoder_never_checks_it(monkeypatch):
    made = []
    check = FringeCodec.__post_init__

    def counted(self):
        made.append(self)
        check(self)

    monkeypatch.setattr(FringeCodec, "__post_init__", counted)
    scene = fringes(size=8, levels=0)
    assert len(made) == 1 and scene.emitter.codec is made[0]
    assert scene.emitter.codec == FringeCodec(levels=0)  # the table's values, as made
    made.clear()

    def refused(self):
        raise AssertionError("a codec was made (and validated) again")

    monkeypatch.setattr(FringeCodec, "__post_init__", refused)
    monkeypatch.setattr(codec_module, "_check_periods", refused)
    em = scene.emitter
    s = np.linspace(5.0, 295.0, 64).reshape(8, 8)
    recorded = np.concatenate([em.codec.sequence(s).reshape(-1, 8, 8)] * 2)
    check_scene(scene)
    decoding = decode_sequence(station_model(scene).coding, recorded, 1.0, PmdSettings())
    np.testing.assert_allclose(decoding.uv[..., 1], s - 150.0, atol=1e-9)
    np.testing.assert_allclose(decoding.uv[..., 0], s - 150.0, atol=1e-9)
    assert em.sequence() == em.codec.frames() and em.white() == em.codec.white()


def test_a_stripes_table_makes_no_codec_until_asked():
    stripes = paper_scene().emitter
    assert "_codec" not in vars(stripes)
    assert stripes.codec == FringeCodec()  # the fringes' defaults, checked when asked
    wide = paper_scene().updated(emitter={"half_size": [1e4, 1e4]}).emitter
    with pytest.raises(SceneError, match="emitter.periods"):
        _ = wide.codec


# --------------------------------------------------------------------------- decodable
def test_an_amplitude_above_the_offset_is_shown_but_not_decoded():
    scene = fringes(offset=0.3, amplitude=0.5)
    codec = scene.emitter.codec
    # the screen shows it: the commanded fringe goes below black and clips there
    shown = codec.radiance(np.linspace(0.0, 2.0, 2001), 0, 0)
    assert shown.min() == 0.0 and (shown == 0.0).mean() > 0.2
    with pytest.raises(SceneError) as info:
        check_scene(scene)
    text = str(info.value)
    assert text.startswith("emitter.amplitude: must be in (0, emitter.offset = 0.3]")
    assert "got 0.5" in text and "\n" not in text
    with pytest.raises(SceneError, match=r"^emitter.amplitude: .* got 0.0$"):
        check_scene(fringes(amplitude=0.0))
    check_scene(fringes(offset=0.4, amplitude=0.4))  # at the offset: decoded
    FringeCodec(offset=0.3, amplitude=0.5)  # the codec itself accepts it


def test_one_decode_names_its_direction_where_the_codec_codes_two():
    codec = FringeCodec(levels=0, screen_half_size_mm=(200.0, 150.0))
    s = np.linspace(1.0, 299.0, 50)
    with pytest.raises(GlshadeError, match="name the direction, one of v, u"):
        pmd.decode(codec.sequence(s), codec)
    assert (codec.extent_mm("u"), codec.extent_mm("v")) == (400.0, 300.0)
    decoded = pmd.decode(codec.sequence(s), codec, direction="v")
    np.testing.assert_allclose(decoded.s_mm, s, atol=1e-9)


# --------------------------------------------------------------------------- the manifest
def test_the_manifest_round_trips_the_codec(tmp_path):
    curve = tmp_path / "screen.csv"
    curve.write_text("0 0.3\n255 250\n")
    codec = FringeCodec(
        periods_mm=(3.0, 24.0, 400.0),
        shifts=6,
        directions=("u",),
        offset=0.45,
        amplitude=0.4,
        levels=1024,
        screen_half_size_mm=(180.0, 120.0),
        screen_black_level=0.002,
        screen_ambient=0.05,
        screen_response_file=str(curve),
    )
    written = json.loads(json.dumps(codec.to_dict()))
    assert FringeCodec.from_dict(written) == codec
    assert list(written)[:4] == ["periods_mm", "shifts", "directions", "directions_note"]
    assert {"phase", "coordinate", "units"} <= set(written)
    assert written["screen_half_size_mm"] == [180.0, 120.0]
    scene = fringes(
        periods=[3.0, 24.0, 400.0], shifts=6, directions=["u"], offset=0.45, amplitude=0.4,
        levels=1024, half_size=[180.0, 120.0], black_level=0.002, ambient=0.05,
        response_file=str(curve),
    )  # fmt: skip
    assert scene.emitter.codec == codec
    with pytest.raises(GlshadeError, match="missing shifts"):
        FringeCodec.from_dict({k: v for k, v in written.items() if k != "shifts"})
    with pytest.raises(SceneError, match="emitter.offset"):
        FringeCodec.from_dict({**written, "offset": 0.7})


# --------------------------------------------------------------------------- the formula
def _commanded(frame, along: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The commanded value at ``s`` (float64) and how far the shader's float32 one may lie
    from it: the cosine's change over where float32 puts ``s`` (the coordinate ``along``
    read back as float32, the sum ``s`` and the fraction ``x``), the float32 cosine's own
    error (a GPU's errs by up to about 2^-20) and the sum's rounding."""
    ds = ULP * (np.abs(along) + s) + 2.0 * ULP * frame.period_mm
    phase = 2.0 * math.pi * s / frame.period_mm - frame.shift_rad
    slope = frame.amplitude * np.abs(np.sin(phase)) * 2.0 * math.pi / frame.period_mm
    rounding = frame.amplitude * 16.0 * ULP + 4.0 * ULP
    return frame.offset + frame.amplitude * np.cos(phase), slope * ds + rounding


def _bound(codec: FringeCodec, c: np.ndarray, dc: np.ndarray) -> np.ndarray:
    """The displayed value's change over ``c ± dc``, plus a few units of float32's last
    place (the response's ``pow`` and the stored value)."""
    hi = codec.displayed(np.clip(c + dc, 0.0, 1.0))
    lo = codec.displayed(np.clip(c - dc, 0.0, 1.0))
    return 0.5 * np.abs(hi - lo) + 16.0 * ULP


@pytest.mark.parametrize("precision", ["fp32", "fp64"])
@pytest.mark.parametrize("levels", [0, 256])
def test_the_formula_is_what_the_shader_renders(renderer, precision, levels):
    """Each frame of the stack against :meth:`FringeCodec.frame_radiance` at the screen
    point the renderer traced: within float32's rounding of that point and of the value.
    On a quantised screen a pixel whose commanded value lies within that rounding of a
    grey level's edge may show the next level (a handful); every other pixel agrees to a
    few units of float32's last place."""
    emitter = {"gamma": 2.2, "levels": levels, "black_level": 0.01, "ambient": 0.02}
    scene = fringes(**emitter).updated(render={"precision": precision})
    em, codec = scene.emitter, scene.emitter.codec
    frames = [f for f in codec.frames() if f.shift_index in (0, 1)]
    out = renderer.render(scene, ("frames", "uv", "mask"), frames=frames)
    uv = out.uv.astype(np.float64)
    seen = out.mask & np.isfinite(uv).all(axis=-1)
    assert seen.mean() > 0.9
    edges = 0
    for layer, frame in zip(out.frames, frames, strict=True):
        along = uv[..., frame.axis][seen]
        s = along + em.half_size[frame.axis]
        error = np.abs(layer[seen].astype(np.float64) - codec.frame_radiance(frame, s))
        c, dc = _commanded(frame, along, s)
        bound = _bound(codec, c, dc)
        if levels:
            # a level's edge within the commanded value's rounding: the shader may round
            # it the other way, to the next level
            q = c * (levels - 1)
            near = np.abs(q - np.floor(q) - 0.5) / (levels - 1) <= dc
            assert error[near].max(initial=0.0) <= codec.largest_step() + 16.0 * ULP
            edges += int(near.sum())
            error, bound = error[~near], np.full(int((~near).sum()), 16.0 * ULP)
        assert np.all(error <= bound), (frame, float(np.max(error / bound)))
    assert edges <= 0.002 * seen.sum() * len(frames)
