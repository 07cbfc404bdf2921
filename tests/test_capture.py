"""Recorded captures in (glshade.capture, docs/captures.md): a ``--frames`` folder read back
decodes as the measurement did, the same frames as image stacks decode the same, the
writers round-trip bit for bit, a foreign coding's conventions decode synthetic frames
exactly, and bad input is one line, exit 2."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from glshade.app.cli import main
from glshade.capture.decode import decode_capture
from glshade.capture.frames_folder import read_frames_folder, write_frames_folder
from glshade.capture.model import Capture, CaptureCoding
from glshade.capture.stack import coding_text, read_stack, write_stack
from glshade.errors import GlshadeError


@pytest.fixture(scope="module")
def measured(tmp_path_factory):
    """A small PMD measurement through a sensor: its float TIFF and 16-bit PNG ``--frames``
    folders and its own decoded map (``--maps``)."""
    folder = tmp_path_factory.mktemp("capture")
    sensor = ["--set", "sensor.full_well_e=10000"]
    for fmt in ("tif", "png"):
        args = ["measure", "--method", "pmd", "--json", "--size", "24", *sensor]
        args += [
            "--frames",
            str(folder / fmt),
            "--frame-format",
            fmt,
            "--maps",
            str(folder / f"maps_{fmt}"),
        ]
        assert main(args) == 0
    return folder


def test_a_frames_folder_decodes_as_the_measurement(measured, capsys):
    theirs = np.load(measured / "maps_tif" / "decoded.npy")
    capture = read_frames_folder(measured / "tif")
    assert capture.scene is not None and capture.white is not None
    mine = decode_capture(capture)
    np.testing.assert_allclose(mine.uv, theirs, atol=1e-9)  # NaN where NaN: the same mask
    assert np.array_equal(mine.valid, np.isfinite(theirs).all(axis=-1))
    assert mine.valid.mean() > 0.5
    # the residual of a noisy capture implies a noise close to the one it has
    assert np.nanmedian(mine.residual[:, mine.valid]) > 0
    assert np.all(mine.margin[:, mine.valid] > 0.25)
    # the 16-bit folder: within its rounding
    png = decode_capture(read_frames_folder(measured / "png"))
    theirs_png = np.load(measured / "maps_png" / "decoded.npy")
    both = np.isfinite(png.uv) & np.isfinite(theirs_png)
    assert np.abs(png.uv - theirs_png)[both].max() < 1e-4


def test_stacks_decode_as_the_folder(measured, tmp_path):
    capture = read_frames_folder(measured / "png")
    reference = decode_capture(capture)
    write_stack(tmp_path / "pngs", capture, tmp_path / "png.toml", "png")
    write_stack(tmp_path / "stack.tif", capture, tmp_path / "tif.toml", "tiff")
    for stack, coding in (("pngs", "png.toml"), ("stack.tif", "tif.toml")):
        again = read_stack(tmp_path / stack, tmp_path / coding)
        assert np.array_equal(again.frames, capture.frames)
        decoded = decode_capture(again)
        np.testing.assert_array_equal(decoded.uv, reference.uv)
        np.testing.assert_array_equal(decoded.valid, reference.valid)


def test_the_writers_round_trip_bit_for_bit(measured, tmp_path):
    for fmt in ("png", "tif"):
        capture = read_frames_folder(measured / fmt)
        write_frames_folder(tmp_path / fmt, capture)
        names = sorted(p.name for p in (measured / fmt).iterdir())
        assert names == sorted(p.name for p in (tmp_path / fmt).iterdir())
        for name in names:
            assert (measured / fmt / name).read_bytes() == (tmp_path / fmt / name).read_bytes(), (
                name
            )
        again = read_frames_folder(tmp_path / fmt)
        assert np.array_equal(again.frames, capture.frames)
        assert np.array_equal(again.white, capture.white)
    # a stack and its coding file
    capture = read_frames_folder(measured / "png")
    write_stack(tmp_path / "s", capture, tmp_path / "s.toml")
    again = read_stack(tmp_path / "s", tmp_path / "s.toml")
    assert again.coding == capture.coding
    assert np.array_equal(again.frames, capture.frames) and np.array_equal(
        again.white, capture.white
    )
    write_stack(tmp_path / "t", again, tmp_path / "t.toml")
    for name in sorted(p.name for p in (tmp_path / "s").iterdir()):
        assert (tmp_path / "s" / name).read_bytes() == (tmp_path / "t" / name).read_bytes()


def synthetic(
    coding: CaptureCoding, u: np.ndarray, v: np.ndarray, a: float, b: float
) -> np.ndarray:
    """Frames built by construction in ``coding``'s conventions: ``I = A + B cos(2π s / p -
    δ_n)``, ``δ_n = shift_sign 2π n / N``, ``s`` from the axis's origin, in its order."""
    frames = np.empty((coding.frame_count, *u.shape))
    points = {"u": u, "v": v}
    for d, direction in enumerate(coding.directions):
        axis = 0 if direction == "u" else 1
        size = coding.screen_size_mm[axis]
        x = points[direction]
        s = x + size / 2 if coding.origin[axis] == "low" else size / 2 - x
        for k in range(len(coding.periods)):
            p = coding.period_mm(direction, k)
            for n in range(coding.shifts):
                delta = coding.shift_sign * 2 * math.pi * n / coding.shifts
                frames[coding.frame_index(d, k, n)] = a + b * np.cos(2 * math.pi * s / p - delta)
    return frames


def test_a_foreign_codings_conventions_decode_exactly():
    coding = CaptureCoding(
        directions=("u", "v"),
        periods=(1.0, 8.0, 64.0),  # fringes per screen, coarsest first
        period_unit="screen",
        order=("period", "shift", "direction"),
        shifts=5,
        shift_sign=-1,
        origin=("high", "low"),
        screen_size_mm=(320.0, 240.0),
    )
    rng = np.random.default_rng(3)
    u = rng.uniform(-159.0, 159.0, (12, 10))
    v = rng.uniform(-119.0, 119.0, (12, 10))
    capture = Capture(synthetic(coding, u, v, 0.45, 0.3), coding, peak_response=1.0)
    decoded = decode_capture(capture)
    assert decoded.valid.all()
    assert np.abs(decoded.uv[..., 0] - u).max() < 1e-9
    assert np.abs(decoded.uv[..., 1] - v).max() < 1e-9
    np.testing.assert_allclose(decoded.fraction[..., 0], (u + 160.0) / 320.0, atol=1e-12)
    assert np.nanmax(decoded.residual) < 1e-12
    np.testing.assert_allclose(decoded.modulation, 0.3, atol=1e-12)
    # the codec glshade sees: mm, finest first
    assert coding.codec("u").periods_mm == (5.0, 40.0, 320.0)
    # black and white references normalise the frames (modulation relative to white - black)
    black, white = np.full(u.shape, 0.1), np.full(u.shape, 0.9)
    scaled = Capture(0.1 + 0.8 * capture.frames, coding, black=black, white=white)
    again = decode_capture(scaled)
    assert again.normalised and np.abs(again.uv - decoded.uv).max() < 1e-9


# --------------------------------------------------------------------------- bad input
def decode_cli(capsys, *args: str) -> tuple[int, str]:
    code = main(["decode", *args])
    return code, capsys.readouterr().err.strip()


def test_bad_input_is_one_line_and_exit_2(measured, tmp_path, capsys):
    out = tmp_path / "out"
    code, err = decode_cli(capsys, str(tmp_path / "none"), "--out", str(out))
    assert code == 2 and len(err.splitlines()) == 1 and "manifest.json" in err
    # a frame missing from a --frames folder
    broken = tmp_path / "broken"
    write_frames_folder(broken, read_frames_folder(measured / "png"))
    (broken / "frame_005_v_p1_n1.png").unlink()
    code, err = decode_cli(capsys, str(broken), "--out", str(out))
    assert code == 2 and len(err.splitlines()) == 1 and "frame_005_v_p1_n1.png" in err
    # an unreadable image, and one of another size
    (broken / "frame_005_v_p1_n1.png").write_text("not an image")
    code, err = decode_cli(capsys, str(broken), "--out", str(out))
    assert code == 2 and "frame_005_v_p1_n1.png" in err and "not a readable" in err
    import cv2

    cv2.imwrite(str(broken / "frame_005_v_p1_n1.png"), np.zeros((5, 5), np.uint16))
    code, err = decode_cli(capsys, str(broken), "--out", str(out))
    assert code == 2 and "frame_005_v_p1_n1.png" in err and "24 x 24" in err
    # a stack with the wrong frame count, and a bad coding file
    capture = read_frames_folder(measured / "png")
    write_stack(tmp_path / "s", capture, tmp_path / "s.toml")
    (tmp_path / "s" / "frame_000.png").unlink()
    code, err = decode_cli(
        capsys, str(tmp_path / "s"), "--coding", str(tmp_path / "s.toml"), "--out", str(out)
    )
    assert (
        code == 2 and len(err.splitlines()) == 1 and "32 frame images" in err and "found 31" in err
    )
    (tmp_path / "bad.toml").write_text(
        coding_text(capture.coding).replace("shifts = 4", "shifts = 2")
    )
    code, err = decode_cli(
        capsys, str(tmp_path / "s"), "--coding", str(tmp_path / "bad.toml"), "--out", str(out)
    )
    assert code == 2 and "bad.toml" in err and "shifts" in err
    with pytest.raises(GlshadeError, match="order"):
        CaptureCoding(("v",), (300.0,), 4, (300.0, 300.0), order=("period", "period", "shift"))
    with pytest.raises(GlshadeError, match="coding.periods"):  # the coarsest spans no screen
        CaptureCoding(("v",), (2.0, 16.0), 4, (300.0, 300.0))
    assert not out.exists()


def test_the_decode_command_writes_its_outputs(measured, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["decode", str(measured / "tif"), "--out", str(out)]) == 0
    capsys.readouterr()
    names = {p.name for p in out.iterdir()}
    assert names == {
        "maps.npz",
        "u.png",
        "v.png",
        "modulation.png",
        "residual.png",
        "periods.png",
        "masks.png",
        "summary.json",
        "summary.md",
    }
    summary = json.loads((out / "summary.json").read_text())
    # the capture's own sensor predicts the noise its fit residual implies (rms over the
    # valid pixels: measured within 2 % at 48 px; here 24 px, so 15 %)
    for axis in ("u", "v"):
        numbers = summary["axes"][axis]
        ratio = numbers["noise_from_residual_rms_mm"] / numbers["predicted_noise_rms_mm"]
        assert 0.85 < ratio < 1.15, (axis, ratio)
    maps = np.load(out / "maps.npz")
    assert summary["valid_share"] == pytest.approx(maps["valid"].mean())
    theirs = np.load(measured / "maps_tif" / "decoded.npy")
    np.testing.assert_allclose(maps["uv"], theirs, atol=1e-9)
    assert set(summary["axes"]) == {"u", "v"}
    assert Path(out / "summary.md").read_text().startswith("# Decoded capture")


# --------------------------------------------------------------------------- response
def _gamma_capture(gamma: float) -> tuple[Capture, np.ndarray, np.ndarray]:
    """A capture whose screen shows c^gamma of its range for a commanded c, with black
    and white references; the true (u, v)."""
    coding = CaptureCoding(("u", "v"), (64.0, 8.0, 1.0), 4, (320.0, 240.0), period_unit="screen")
    rng = np.random.default_rng(5)
    u = rng.uniform(-150.0, 150.0, (9, 11))
    v = rng.uniform(-110.0, 110.0, (9, 11))
    commanded = synthetic(coding, u, v, 0.5, 0.45)
    black, white = np.full(u.shape, 12.0), np.full(u.shape, 230.0)
    recorded = black + (white - black) * commanded**gamma
    return Capture(recorded, coding, black=black, white=white), u, v


def test_a_gamma_response_is_undone_exactly():
    from glshade.capture.decode import DecodeSettings
    from glshade.capture.response_files import parse_response

    capture, u, v = _gamma_capture(2.2)
    settings = DecodeSettings(response=parse_response("gamma:2.2"), mask="all")
    decoded = decode_capture(capture, settings=settings)
    assert decoded.valid.all() and decoded.response == "gamma 2.2"
    assert (
        np.abs(decoded.uv[..., 0] - u).max() < 1e-9 and np.abs(decoded.uv[..., 1] - v).max() < 1e-9
    )
    assert np.nanmax(decoded.residual) < 1e-12
    linear = decode_capture(capture, settings=DecodeSettings(mask="all"))
    assert np.nanmax(np.abs(linear.uv[..., 0] - u)) > 1e-3  # the harmonics bias the phase
    assert np.nanmedian(linear.residual) > 1e-3


def test_a_measured_curve_is_undone_exactly(tmp_path):
    """A screen whose response is piecewise linear: the measured curve (recorded,
    commanded) at its knots, as CSV and as TOML, decodes exactly."""
    from glshade.capture.decode import DecodeSettings
    from glshade.capture.response_files import parse_response

    knots_c = np.array([0.0, 0.2, 0.5, 0.8, 1.0])
    knots_r = np.array([10.0, 25.0, 80.0, 170.0, 240.0])
    capture, u, v = _gamma_capture(1.0)
    commanded = (capture.frames - 12.0) / (230.0 - 12.0)
    recorded = np.interp(commanded, knots_c, knots_r)
    curved = Capture(
        recorded, capture.coding, black=np.full(u.shape, 10.0), white=np.full(u.shape, 240.0)
    )
    (tmp_path / "r.csv").write_text(
        "recorded,commanded\n"
        + "".join(f"{r},{c}\n" for r, c in zip(knots_r, knots_c, strict=True))
    )
    (tmp_path / "r.toml").write_text(
        f"recorded = {knots_r.tolist()}\ncommanded = {knots_c.tolist()}\n"
    )
    for name in ("r.csv", "r.toml"):
        response = parse_response(str(tmp_path / name))
        decoded = decode_capture(curved, settings=DecodeSettings(response=response, mask="all"))
        assert np.abs(decoded.uv[..., 0] - u).max() < 1e-9, name
        assert np.abs(decoded.uv[..., 1] - v).max() < 1e-9, name


def test_bad_responses_and_noise_are_one_line(measured, tmp_path, capsys):
    out = tmp_path / "out"
    folder = str(measured / "tif")
    (tmp_path / "bad.csv").write_text("1,2\n3,x\n")
    for flags, needle in (
        (["--response", "gamma:-1"], "--response gamma:-1: gamma:G"),
        (["--response", str(measured / "tif" / "manifest.json")], "a .csv, .toml or .h5"),
        (["--response", "gamma:abc"], "gamma:G"),
        (["--response", str(tmp_path / "none.csv")], "no such file"),
        (["--response", str(tmp_path / "bad.csv")], "bad.csv:2"),
        (["--noise", "read=1"], "read=R,gain=G"),
        (["--noise", "read=1,gain=-2"], "at least 0"),
        (["--display", str(tmp_path / "d.h5")], "SOFAST capture"),
    ):
        code, err = decode_cli(capsys, folder, "--out", str(out), *flags)
        assert code == 2 and len(err.splitlines()) == 1 and needle in err, (flags, err)
    assert not out.exists()


def test_the_captures_own_response_is_applied_unless_told_another():
    """A capture carries its station's response; decode_capture applies it, and a
    response given to decode_capture wins over it."""
    from dataclasses import replace

    from glshade.capture.response import Response

    capture, u, v = _gamma_capture(2.2)
    own = replace(capture, response=Response("gamma", gamma=2.2))
    decoded = decode_capture(own)
    assert decoded.response == "gamma 2.2" and decoded.peak == 1.0
    assert np.abs(decoded.uv[..., 0] - u).max() < 1e-9
    other = decode_capture(own, response=Response("gamma", gamma=1.0))
    assert other.response == "gamma 1" and np.nanmax(np.abs(other.uv[..., 0] - u)) > 1e-3


# --------------------------------------------------------------------------- rules
def _blurred_capture() -> tuple[Capture, np.ndarray, np.ndarray, dict[str, tuple[int, int]]]:
    """A linear screen (modulation 0.45 of white - black, threshold 0.05) whose finest u
    fringe is blurred to 0.036 at one pixel (above half the threshold), to 0.018 at
    another (below it), and whose finest u phase is 0.4 of a turn off at a third."""
    capture, u, v = _gamma_capture(1.0)
    frames = np.array(capture.frames)
    coding = capture.coding
    finest = coding.finest_first("u")[0]
    shifted = synthetic(coding, u + 0.4 * coding.period_mm("u", finest), v, 0.5, 0.45)
    pixels = {"blurred": (1, 2), "faint": (4, 5), "shifted": (7, 8)}
    for n in range(coding.shifts):
        i = coding.frame_index(coding.directions.index("u"), finest, n)
        for name, factor in (("blurred", 0.08), ("faint", 0.04)):
            y, x = pixels[name]
            frames[i, y, x] = 12.0 + 218.0 * (
                0.5 + factor * ((frames[i, y, x] - 12.0) / 218.0 - 0.5)
            )
        y, x = pixels["shifted"]
        frames[i, y, x] = 12.0 + 218.0 * shifted[i, y, x]
    return Capture(frames, coding, black=capture.black, white=capture.white), u, v, pixels


def test_the_per_period_rule_keeps_a_blurred_finest_fringe_exactly():
    """ "all" drops the blurred pixel (and takes the shifted one 2 mm off, unseen);
    "fallback" keeps it from the next period; "periods" keeps it from its own finest
    phase, exact, and reports the finest period as not sound; the faint one and the
    shifted one (margin 0.1 turn) come from the next period."""
    from glshade.capture.decode import DecodeSettings

    capture, u, v, px = _blurred_capture()
    got = {
        rule: decode_capture(capture, settings=DecodeSettings(rule=rule, mask="all"))
        for rule in ("all", "fallback", "periods")
    }
    blurred, faint, shifted = px["blurred"], px["faint"], px["shifted"]
    assert not got["all"].valid[blurred] and not got["all"].valid[faint]
    assert abs(got["all"].uv[shifted][0] - u[shifted]) > 1.0
    assert got["fallback"].finest_used[0][blurred] == 1
    assert abs(got["fallback"].uv[blurred][0] - u[blurred]) < 1e-9  # exact frames here
    periods = got["periods"]
    assert periods.valid.all()
    assert periods.finest_used[0][blurred] == 0 and not periods.period_valid[0, 0][blurred]
    assert periods.finest_used[0][faint] == 1 and periods.finest_used[0][shifted] == 1
    assert abs(periods.uv[blurred][0] - u[blurred]) < 1e-9
    assert abs(periods.uv[shifted][0] - u[shifted]) < 1e-9
    assert periods.margin[0][shifted] > 0.25 and got["all"].margin[0][shifted] < 0.15
    others = np.ones(u.shape, bool)
    for y, x in px.values():
        others[y, x] = False
    assert (periods.finest_used[0][others] == 0).all() and (periods.finest_used[1] == 0).all()
    assert (
        np.abs(periods.uv[..., 0] - u).max() < 1e-9 and np.abs(periods.uv[..., 1] - v).max() < 1e-9
    )


def test_the_decode_status_names_what_is_at_risk():
    from glshade.app.commands.decode import decode_status

    good = {"least_margin_turns": 0.4}
    assert decode_status({"u": good, "v": good}) == ("ok", "")
    status, reason = decode_status({"u": good, "v": {"least_margin_turns": 0.04}})
    assert status == "unwrapping at risk" and "v 0.040" in reason
    status, reason = decode_status({"u": {"least_margin_turns": None}, "v": good})
    assert status == "no valid pixel" and "along u" in reason
