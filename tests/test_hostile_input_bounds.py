"""Hostile input, bounded: a quantity of 120 000 digits, a unit in the wrong case, a fringe
period of 1e300 mm, a memory budget of 1e303 MiB, an image header declaring 16384² samples
and a fringe sequence of 24 000 frames are each refused before any work, in one line
naming what was typed and what is allowed (exit 2, no traceback), and the PMD memory
estimate grows with the frames at least as fast as the memory a measurement takes.

Where the command line is under test, it runs as a user runs it (a fresh interpreter,
:mod:`glshade_process`), with a timeout: a parser that backtracks fails the test instead
of hanging the suite. No test asserts a time."""

from __future__ import annotations

import re
import struct
import subprocess
import tracemalloc
import zlib
from pathlib import Path

import numpy as np
import pytest

from glshade.budget import MEMORY_BUDGET_RANGE_MB, memory_budget_from_env
from glshade.errors import SceneError
from glshade.image_header import ImageHeaderError, check_pixels, image_header
from glshade.instruments import memory
from glshade.instruments.pmd.station import measure_pmd_scene
from glshade.measure.single import as_method
from glshade.scene import Scene, paper_scene
from glshade.units import MAX_QUANTITY_CHARS, QuantityError, parse_quantity
from glshade_process import run_glshade

#: The hostile quantities of the report: 60 KB of digits and junk, 120 000 digits.
JUNK = "1" * 60_000 + " x y"
DIGITS = "1" * 120_000
FAMILY = f"defect.dmax={DIGITS}x..5um"
#: A hang is a failure, not a wait: each command here ends in about a second.
TIMEOUT_S = 20


def one_line(result: subprocess.CompletedProcess, *fragments: str) -> str:
    """The run's one error line (exit 2, nothing on stdout, no traceback), which names
    ``fragments``."""
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2, result.stderr[-2000:]
    assert len(lines) == 1 and "Traceback" not in result.stderr, result.stderr[-2000:]
    assert lines[0].startswith("glshade: error: "), lines[0]
    for fragment in fragments:
        assert fragment in lines[0], lines[0]
    return lines[0]


def glshade(*args: str, cwd: Path, env: dict[str, str | None] | None = None):
    return run_glshade(*args, cwd=cwd, env=env, timeout=TIMEOUT_S)


# --------------------------------------------------------------------------- A. parsing
def _sweep_file(folder: Path) -> list[str]:
    (folder / "sweep.toml").write_text(f'size = 8\n[grid]\n"defect.dmax" = ["{JUNK}"]\n')
    return ["sweep", "sweep.toml", "--out", "swept", "--yes", "--no-progress"]


def _scene_file(folder: Path) -> list[str]:
    (folder / "long.toml").write_text(f'[defect]\ndmax = "{JUNK}"\n')
    return ["render", "long.toml", "--size", "8", "-o", "out.png"]


HUGE_QUANTITIES = {
    "scene file": (_scene_file, "defect.dmax: ", "60004 characters"),
    "--set": (
        lambda _: ["render", "--set", f"defect.dmax={DIGITS}", "--size", "8", "-o", "out.png"],
        "defect.dmax: ",
        "120000 characters",
    ),
    "a flag": (
        lambda _: ["render", "--dmax", DIGITS + " x y", "--size", "8", "-o", "out.png"],
        "argument --dmax: defect.dmax: ",
        "120004 characters",
    ),
    "sweep grid": (_sweep_file, "grid.defect.dmax: ", "60004 characters"),
    "--family": (
        lambda _: ["optimize", "--over", "camera.theta_deg=5..40", "--family", FAMILY],
        "--family defect.dmax: ",
        "120001 characters",
    ),
}


@pytest.mark.parametrize("where", list(HUGE_QUANTITIES))
def test_a_huge_quantity_is_one_short_line_wherever_it_is_typed(tmp_path, where):
    build, field, length = HUGE_QUANTITIES[where]
    line = one_line(glshade(*build(tmp_path), cwd=tmp_path), field, length)
    assert f"at most {MAX_QUANTITY_CHARS} characters" in line
    assert "'111111111111111111111111'..." in line  # an excerpt of what was typed
    assert len(line) < 300
    assert all(p.suffix == ".toml" for p in tmp_path.iterdir())  # nothing written


def test_the_length_limit_is_exact():
    text = "0" * (MAX_QUANTITY_CHARS - 5) + "1 mm"  # blanks around it are not counted
    assert parse_quantity(f"  {text} \t", "mm", "f") == 1.0
    with pytest.raises(QuantityError, match=rf"^f: .*got {MAX_QUANTITY_CHARS + 1} characters"):
        parse_quantity("0" + text + "0", "mm", "f")


@pytest.mark.parametrize(
    ("text", "unit", "value"),
    [
        (".5mm", "mm", 0.5),
        ("5.mm", "mm", 5.0),
        ("+2 cm", "mm", 20.0),
        ("1e-3 m", "mm", 1.0),
        ("1E3nm", "mm", 1e-3),
        ("5 µm", "mm", 0.005),
        ("5μm", "mm", 0.005),  # the Greek mu as well as the micro sign
        ("4 mm^2", "mm²", 4.0),
        ("-3 mrad", "deg", -0.18 * 3 / np.pi),
        ("550 nm", "µm", 0.55),
    ],
)
def test_the_scanner_reads_every_spelling(text, unit, value):
    assert parse_quantity(text, unit, "f") == pytest.approx(value, rel=1e-12)


@pytest.mark.parametrize(
    ("text", "unit", "meant", "meaning"),
    [
        ("0.005 Mm", "mm", "mm", "(Mm would be megametres)"),
        ("0.005MM", "mm", "mm", ""),
        ("5 UM", "mm", "um", ""),
        ("4 Mm2", "mm²", "mm2", ""),
        ("15 DEG", "deg", "deg", ""),
        ("0.2 Rad", "deg", "rad", ""),
        ("5 M", "mm", "m", "(M would be the prefix mega)"),
    ],
)
def test_units_are_case_sensitive(text, unit, meant, meaning):
    with pytest.raises(QuantityError) as info:
        parse_quantity(text, unit, "defect.dmax")
    message = str(info.value)
    assert message.startswith("defect.dmax: unit ")
    assert f"did you mean {meant}? units are case-sensitive" in message
    assert meaning in message and "\n" not in message


def test_a_wrong_case_unit_is_one_line_in_a_scene_and_on_the_command_line(tmp_path):
    with pytest.raises(SceneError, match=r"did you mean mm\? units are case-sensitive"):
        Scene().with_value("defect.dmax", "0.005 Mm")
    result = glshade("render", "--set", "defect.dmax=0.005Mm", "-o", "o.png", cwd=tmp_path)
    one_line(result, "defect.dmax: unit 'Mm'", "did you mean mm?", "megametres")
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------- B. ranges
def fringes(periods) -> Scene:
    return Scene().with_values([("emitter.kind", "fringes"), ("emitter.periods", periods)])


def test_a_period_beyond_a_million_screens_is_refused():
    assert fringes([2.0, 3e8]).emitter.periods == (2.0, 3e8)  # 1e6 x the 300 mm screen
    for periods in ([1e300], [2.0, 3.1e8]):
        with pytest.raises(SceneError) as info:
            fringes(periods)
        message = str(info.value)
        assert message.startswith("emitter.periods: must be periods in (1e-06, 3e+08] mm")
        assert "1e+06 times the screen's extent 2 half_size = 300 mm" in message
        assert message.endswith(f"got {periods[-1]!r}")


def test_a_period_of_1e300_is_one_line_and_no_warning(tmp_path):
    (tmp_path / "far.toml").write_text('[emitter]\nkind = "fringes"\nperiods = [1e300]\n')
    result = glshade("measure", "far.toml", "--method", "pmd", "--size", "16", cwd=tmp_path)
    one_line(result, "emitter.periods: ", "(1e-06, 3e+08] mm", "got 1e+300")
    assert "RuntimeWarning" not in result.stderr and result.stdout == ""


@pytest.mark.parametrize(
    "key, typed, said",
    [
        ("emitter.period", "1e+300", 'must be in (1e-06, 1e+09) mm or "auto"'),
        ("sensor.full_well_e", "5e-324", "must be in [1, 1e+09] e-"),
        ("sensor.read_noise_e", "1e+300", "must be in [0, 1e+09] e-"),
    ],
)
def test_a_stripe_period_and_a_sensor_beyond_their_range_are_one_line(key, typed, said):
    """A stripe period of 1e300 mm (which printed a 300-digit phase count), a full well
    of 5e-324 e- (an infinite black level: OverflowError) are refused by their range."""
    with pytest.raises(SceneError, match=re.escape(f"{key}: {said}, got {typed}")):
        Scene().with_value(key, float(typed))


def test_the_memory_budget_has_a_range(monkeypatch):
    low, high = MEMORY_BUDGET_RANGE_MB
    monkeypatch.setenv("GLSHADE_MEMORY_BUDGET_MB", f"{low:g}")
    assert memory_budget_from_env() == 1 << 20
    monkeypatch.setenv("GLSHADE_MEMORY_BUDGET_MB", f"{high:.0f}")
    assert memory_budget_from_env() == 1 << 50
    for typed in ("1e303", "0.5", "0", "-4", "inf", "nan", str(int(high) + 1), "x"):
        monkeypatch.setenv("GLSHADE_MEMORY_BUDGET_MB", typed)
        with pytest.raises(SceneError) as info:
            memory_budget_from_env()
        assert str(info.value) == (
            f"GLSHADE_MEMORY_BUDGET_MB: must be a number of MiB in [1, 1073741824] (2^30 MiB), "
            f"got {typed!r}"
        )


def _height_map_scene(folder: Path) -> list[str]:
    np.save(folder / "heights.npy", np.zeros((16, 16)))
    (folder / "map.toml").write_text(
        '[surface]\nkind = "heightmap"\nfile = "heights.npy"\nspacing = [1.0, 1.0]\n'
    )
    return ["render", "map.toml", "--size", "8", "-o", "out.png"]


@pytest.mark.parametrize("scene", ["default", "height map"])
def test_a_budget_of_1e303_names_the_variable_not_the_height_map(tmp_path, scene):
    argv = (
        ["render", "--size", "8", "-o", "out.png"]
        if scene == "default"
        else _height_map_scene(tmp_path)
    )
    result = glshade(*argv, cwd=tmp_path, env={"GLSHADE_MEMORY_BUDGET_MB": "1e303"})
    line = one_line(result, "GLSHADE_MEMORY_BUDGET_MB: ", "[1, 1073741824]", "got '1e303'")
    assert "surface.file" not in line and "height map" not in line
    assert not (tmp_path / "out.png").exists()


# --------------------------------------------------------------------------- C. memory
def _png(path: Path, width: int, height: int, bits: int = 16, colour: int = 0) -> None:
    """A PNG whose IHDR declares ``width`` x ``height``; its image data a token (the
    header is all a header reader may look at)."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        crc = struct.pack(">I", zlib.crc32(kind + data))
        return struct.pack(">I", len(data)) + kind + data + crc

    ihdr = struct.pack(">IIBBBBB", width, height, bits, colour, 0, 0, 0)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", ihdr)
        + chunk(b"IDAT", zlib.compress(bytes(1000)))
        + chunk(b"IEND", b"")
    )


def _tiff(path: Path, width: int, height: int) -> None:
    """A classic little-endian TIFF whose first page declares ``width`` x ``height``
    16-bit samples, one strip of ten bytes."""
    tags = [(256, 4, width), (257, 4, height), (258, 3, 16), (259, 3, 1), (262, 3, 1)]
    tags += [(273, 4, 8), (277, 3, 1), (278, 4, height), (279, 4, 10)]
    ifd = struct.pack("<H", len(tags)) + b"".join(
        struct.pack("<HHII", tag, kind, 1, value) for tag, kind, value in tags
    )
    path.write_bytes(b"II*\x00" + struct.pack("<I", 8) + ifd + struct.pack("<I", 0))


def test_image_header_reads_png_and_tiff_headers_only(tmp_path):
    _png(tmp_path / "bomb.png", 16384, 16384)
    _png(tmp_path / "rgba.png", 7, 5, bits=8, colour=6)
    _tiff(tmp_path / "bomb.tif", 100_000, 50_000)
    bomb = image_header(tmp_path / "bomb.png")
    assert (bomb.kind, bomb.width, bomb.height, bomb.bit_depth, bomb.channels) == (
        "png", 16384, 16384, 16, 1,
    )  # fmt: skip
    assert bomb.decoded_bytes == 16384 * 16384 * 2  # 512 MiB from a file of about 1 KB
    rgba = image_header(tmp_path / "rgba.png")
    assert (rgba.width, rgba.height, rgba.bit_depth, rgba.channels) == (7, 5, 8, 4)
    tiff = image_header(tmp_path / "bomb.tif")
    assert (tiff.kind, tiff.width, tiff.height, tiff.bit_depth, tiff.channels) == (
        "tiff", 100_000, 50_000, 16, 1,
    )  # fmt: skip
    with pytest.raises(ImageHeaderError) as info:
        check_pixels(bomb, 1 << 24, "baseline bomb.png")
    assert str(info.value) == (
        "baseline bomb.png: declares 16384 x 16384 pixels, 16-bit, 1 channel = 268435456 "
        "pixels, more than the 16777216 allowed; nothing was decoded"
    )
    check_pixels(rgba, 35, "rgba.png")  # exactly at the limit


@pytest.mark.parametrize(
    ("content", "said"),
    [
        (b"GIF89a" + bytes(40), "is neither a PNG nor a TIFF"),
        (b"\x89PNG\r\n\x1a\n" + bytes(10), "is not a PNG"),
        (b"II*\x00" + struct.pack("<I", 4000), "is a damaged TIFF"),
        (b"", "is neither a PNG nor a TIFF"),
    ],
)
def test_a_damaged_header_is_one_line(tmp_path, content, said):
    (tmp_path / "x.png").write_bytes(content)
    with pytest.raises(ImageHeaderError, match=said) as info:
        image_header(tmp_path / "x.png", "baseline")
    assert str(info.value).startswith("baseline ") and "\n" not in str(info.value)


def test_a_damaged_png_header_is_named(tmp_path):
    _png(tmp_path / "crc.png", 8, 8)
    data = bytearray((tmp_path / "crc.png").read_bytes())
    data[17] ^= 1  # a bit of the width: the CRC no longer matches
    (tmp_path / "crc.png").write_bytes(bytes(data))
    with pytest.raises(ImageHeaderError, match="its IHDR fails its CRC"):
        image_header(tmp_path / "crc.png")
    _png(tmp_path / "depth.png", 8, 8, bits=3)
    with pytest.raises(ImageHeaderError, match="bit depth 3 with colour type 0"):
        image_header(tmp_path / "depth.png")


def test_a_height_map_bomb_is_refused_from_its_header(tmp_path):
    _png(tmp_path / "bomb.png", 16384, 16384)
    (tmp_path / "bomb.toml").write_text(
        '[surface]\nkind = "heightmap"\nfile = "bomb.png"\nspacing = [0.1, 0.1]\n'
    )
    result = glshade("render", "bomb.toml", "--size", "8", "-o", "out.png", cwd=tmp_path)
    one_line(result, "16384 x 16384 = 268435456 samples", "at most ", "GLSHADE_MEMORY_BUDGET_MB")
    assert not (tmp_path / "out.png").exists()


def _coded(periods: int, sensor: bool) -> Scene:
    """The paper's scene at 32², measured by one direction of three-step fringes of
    ``periods`` periods (three frames each)."""
    scene = as_method(paper_scene().with_size(32), "pmd").with_values(
        [
            ("emitter.periods", list(np.geomspace(2.0, 1024.0, periods))),
            ("emitter.directions", ("v",)),
            ("emitter.shifts", 3),
        ]
    )
    return scene.with_value("sensor.full_well_e", 10000.0) if sensor else scene


def _pmd_peak(renderer, scene: Scene) -> int:
    """tracemalloc's peak (bytes) of one PMD measurement of ``scene``, baseline included."""
    tracemalloc.start()
    try:
        measure_pmd_scene(renderer, scene)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize("sensor", [False, True], ids=["radiance", "sensor"])
@pytest.mark.parametrize("gpu", [False, True], ids=["numpy", "gpu"])
def test_the_pmd_estimate_grows_with_the_frames_as_the_peak_does(
    renderer, sensor, gpu, monkeypatch
):
    """From 4 to 20 periods the measured peak grows by about 108 bytes a pixel and period
    (144 with a sensor: its recorded copy and the twin's decoding) where the frames are
    read back, recorded and decoded in NumPy; the estimate must grow by at least as much
    (before it counted the decoder's work and the decodings held, it grew by 72 and 84,
    and 3000 periods took 2.6 GiB where it said 2.0). On the GPU only the maps come
    back: the host holds less, within the same estimate."""
    if not gpu:
        monkeypatch.setattr("glshade.instruments.pmd.shots.on_gpu", lambda *_: False)
    few, many = _coded(4, sensor), _coded(20, sensor)
    for scene in (few, many):  # the first runs also make what is made once (programs)
        _pmd_peak(renderer, scene)
    peaks = [_pmd_peak(renderer, scene) for scene in (few, many)]
    estimates = [memory.pmd_estimate(scene).required_bytes for scene in (few, many)]
    grown, estimated = peaks[1] - peaks[0], estimates[1] - estimates[0]
    assert grown > 16 * 32 * 32 * (60 if not gpu else 24)  # the frames or maps take memory
    assert grown <= estimated, (peaks, estimates)
    assert peaks[1] <= estimates[1]


def test_a_sequence_of_24000_frames_is_refused_before_any_work(tmp_path):
    """3000 periods at 85²: the estimate that left out the decoder's work said 2.0 GiB
    and let it run to 2.6 GiB of resident memory; it is now refused, in one line."""
    periods = ", ".join(f"{p:.6f}" for p in np.linspace(2.0, 1024.0, 3000))
    (tmp_path / "many.toml").write_text(f'[emitter]\nkind = "fringes"\nperiods = [{periods}]\n')
    argv = ["measure", "many.toml", "--method", "pmd", "--size", "85", "--json"]
    result = glshade(*argv, cwd=tmp_path, env={"GLSHADE_MEMORY_BUDGET_MB": None})
    line = one_line(result, "85 x 85 pixels", "24000 frames: 2 directions x 3000 periods")
    assert "more than the memory budget of 2048 MiB (GLSHADE_MEMORY_BUDGET_MB)" in line
    assert "at most --size " in line and "or fewer frames" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["many.toml"]
