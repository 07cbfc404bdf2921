"""Every kind of bad input a user can give: exit code 2, one line on stderr naming the
file or field, never a traceback, nothing written.

Each case runs the real ``glshade`` in a subprocess, in a directory holding the fixture
files below; the directory's listing must be the same afterwards.
"""

from __future__ import annotations

import os
import subprocess
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from glshade_process import run_glshade

#: (arguments, fragment the one error line must contain, extra environment).
BAD_INPUTS: list[tuple[list[str], str, dict[str, str]]] = [
    # scene files
    (
        ["render", "latin1.toml"],
        "scene file latin1.toml: must be UTF-8 text (byte 0xe9 on line 2",
        {},
    ),
    (
        ["render", "image.png"],
        "scene file image.png: must be a TOML text file (this is a PNG image)",
        {},
    ),
    (["render", "adir"], "scene file adir: must be a TOML file, not a directory", {}),
    (["render", "missing.toml"], "scene file: must be an existing TOML file", {}),
    (["render", "broken.toml"], "scene file broken.toml: must be valid TOML", {}),
    (["render", "nul.toml"], "NUL bytes", {}),
    (["render", "big.toml"], "at most 1 MiB", {}),
    (["render", "utf16.toml"], "this is UTF-16 text", {}),
    (["render", "table.toml"], "lens: must be one of the tables", {}),
    (["render", "key.toml"], "camera.zoom: must be one of the keys", {}),
    (
        ["render", "string.toml"],
        "camera.theta_deg: must be in (0.001, 90) degrees (a number in degrees, or with a unit: "
        "15deg, 0.26rad), got '45 parsecs'",
        {},
    ),
    (["render", "range.toml"], "camera.theta_deg: must be in (0.001, 90) degrees, got 120.0", {}),
    (["render", "scalar.toml"], "camera: must be a table of keys", {}),
    (["measure", "latin1.toml"], "scene file latin1.toml: must be UTF-8 text", {}),
    (["view", "image.png"], "this is a PNG image", {}),
    # values and flags
    (["render", "--theta", "95"], "--theta (camera.theta_deg): must be in (0.001, 90) degrees", {}),
    (["render", "--theta", "nan"], "--theta (camera.theta_deg): must be a finite number", {}),
    (["render", "--dmax", "5xx"], "defect.dmax: must be a number in mm, or with a unit", {}),
    (["render", "--dmax", "5kg"], "units: cm, m, mm, nm, um", {}),
    (["render", "--sigma2", "-1"], "--sigma2 (defect.sigma2): must be in (1e-06, 1e+08) mm²", {}),
    (["render", "--size", "0"], "--size (camera.width): must be an integer in [1, 16384]", {}),
    (
        ["render", "--supersample", "17"],
        "--supersample (render.supersample): must be an integer in [1, 16]",
        {},
    ),
    (["render", "--surface", "torus"], "invalid choice: 'torus'", {}),
    (["render", "--set", "camera.zoom=2"], "camera.zoom: must be one of the keys", {}),
    (["render", "--set", "theta"], "expected NAME=VALUE", {}),
    (["render", "--set", "black_level=3"], "--set black_level: ambiguous short name", {}),
    (["render", "--set", "emitter.half_size=1"], "emitter.half_size: must be two numbers", {}),
    (
        ["render", "--size", "4096", "--supersample", "16", "--f-number", "8", "--focus", "431.6"],
        "= 2.75e+11 rays, more than the work budget",
        {},
    ),
    (["render", "--no-such-flag"], "unrecognized arguments: --no-such-flag", {}),
    # optics and sensor
    (
        ["render", "--f-number", "-2"],
        "--f-number (camera.f_number): must be a finite number >= 0 (0: pinhole), got -2.0",
        {},
    ),
    (
        ["render", "--roughness", "-0.01"],
        "--roughness (render.roughness): must be a finite number >= 0, got -0.01",
        {},
    ),
    (
        ["render", "--wavelength", "0"],
        "--wavelength (render.wavelength_um): must be a finite number > 0, got 0.0",
        {},
    ),
    (
        ["render", "--height-rms", "-0.1"],
        "--height-rms (render.height_rms_um): must be a finite number >= 0, got -0.1",
        {},
    ),
    (
        ["render", "--distortion=-20,0,0,0,0"],
        "--distortion (camera.distortion): must be coefficients whose map does not fold",
        {},
    ),
    (
        ["render", "--distortion", "0.1,0.2"],
        "--distortion (camera.distortion): must be a list of 5 finite numbers",
        {},
    ),
    (
        ["render", "--bit-depth", "13"],
        "--bit-depth (sensor.bit_depth): must be one of 8, 10, 12, 16, got 13",
        {},
    ),
    (
        ["render", "--aperture-samples", "0"],
        "--aperture-samples (camera.aperture_samples): must be an integer in [1, 1024]",
        {},
    ),
    (["frobnicate"], "invalid choice: 'frobnicate'", {}),
    # outputs
    (["render", "-o", "out.jpg"], "-o out.jpg: .jpg is a lossy format", {}),
    (
        ["render", "-o", "out.bmp"],
        "-o out.bmp: the extension .bmp is not supported; use one of .png, .tif",
        {},
    ),
    (["render", "-o", "adir"], "-o adir: is a directory; glshade only writes regular files", {}),
    (["render", "-o", "fifo.png"], "-o fifo.png: is a FIFO; glshade only writes regular files", {}),
    (["render", "-o", "no/such/dir/x.png"], "directory no/such/dir does not exist", {}),
    (
        ["render", "--uv", "uv.txt"],
        "--uv uv.txt: the extension .txt is not supported; use one of .npy",
        {},
    ),
    (["render", "--save-scene", "scene.json"], "--save-scene scene.json: the extension .json", {}),
    (
        ["render", "--save-scene", "fifo.toml", "--size", "8"],
        "--save-scene fifo.toml: is a FIFO",
        {},
    ),
    (["render", "--bits", "32", "-o", "x.png"], "--bits 32 (float radiance) needs a .tif", {}),
    (["measure", "--overlay", "o.jpg"], "--overlay o.jpg: .jpg is a lossy format", {}),
    (["measure", "--step", "5"], "step", {}),
    (["paper", "--out", "latin1.toml"], "--out latin1.toml: is not a directory", {}),
    (["paper", "--out", "fifo.png"], "--out fifo.png: is not a directory", {}),
    (["paper", "--out", ""], "argument --out: expected a path, got an empty string", {}),
    (
        ["paper", "--threads", "0", "--out", "p"],
        "--threads: must be an integer in [1, 512], got 0",
        {},
    ),
    (
        ["paper", "--workers", "x", "--out", "p"],
        '--workers: must be an integer in [0, 256] or "auto", got x',
        {},
    ),
    (
        ["paper", "--step", "0.0001", "--out", "p"],
        "step: must give at most 2000 phases per stripe period",
        {},
    ),
    (["measure", "--step", "0.3um"], "got 0.0003 mm = 6667 phases", {}),
    (["paper", "--thetas", "95", "--out", "p"], "thetas", {}),
    (["paper", "--dmaxs", "3xx"], "defect.dmax: must be a number in mm, or with a unit", {}),
    (
        ["view", "--set", "theta=120"],
        "--set theta (camera.theta_deg): must be in (0.001, 90) degrees, got 120.0",
        {},
    ),
    (["view", "--screenshot", "fifo.png", "--frames", "1"], "--screenshot fifo.png: is a FIFO", {}),
    (
        ["view", "--frames", "1"],
        "the viewer needs a display and none is set",
        {"DISPLAY": "", "WAYLAND_DISPLAY": ""},
    ),
    (["accuracy", "--repeats", "0"], "--repeats: must be an integer >= 1", {}),
    # environment
    (["render", "--device", "5"], "--device 5: must be an EGL device index in [0,", {}),
    (["info"], "GLSHADE_EGL_DEVICE: must be an integer >= 0", {"GLSHADE_EGL_DEVICE": "gpu"}),
    (
        ["render", "--size", "8"],
        "GLSHADE_MAX_RAYS: must be a number of rays >= 1",
        {"GLSHADE_MAX_RAYS": "-1"},
    ),
    (
        ["render", "--size", "64"],
        "more than the work budget of 1e+03 rays",
        {"GLSHADE_MAX_RAYS": "1000"},
    ),
    (
        ["render", "--size", "8"],
        "GLSHADE_MEMORY_BUDGET_MB: must be a number of MiB in [1, 1073741824]",
        {"GLSHADE_MEMORY_BUDGET_MB": "x"},
    ),
]


def _fixtures(root: Path) -> None:
    """The files the bad inputs name."""
    (root / "latin1.toml").write_bytes(b"[camera]\n# caf\xe9\ntheta_deg = 45\n")
    (root / "image.png").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(64))
    (root / "adir").mkdir()
    (root / "broken.toml").write_text("[camera\n")
    (root / "nul.toml").write_bytes(b"[camera]\x00\n")
    (root / "big.toml").write_text("# padding\n" * 120_000)
    (root / "utf16.toml").write_bytes("[camera]\ntheta_deg = 45\n".encode("utf-16"))
    (root / "table.toml").write_text("[lens]\nf = 2\n")
    (root / "key.toml").write_text("[camera]\nzoom = 2\n")
    (root / "string.toml").write_text('[camera]\ntheta_deg = "45 parsecs"\n')
    (root / "range.toml").write_text("[camera]\ntheta_deg = 120.0\n")
    (root / "scalar.toml").write_text("camera = 5\n")
    os.mkfifo(root / "fifo.png")
    os.mkfifo(root / "fifo.toml")


def _listing(root: Path) -> dict[str, int]:
    return {str(p.relative_to(root)): p.lstat().st_size for p in sorted(root.rglob("*"))}


def _run(args: list[str], cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess:
    return run_glshade(*args, cwd=cwd, env=env)


@pytest.fixture(scope="module")
def bad_input_results(tmp_path_factory):
    """Every case, run two at a time (each is a fresh interpreter, ~0.3 s)."""
    root = tmp_path_factory.mktemp("bad_input")
    _fixtures(root)
    before = _listing(root)
    with ThreadPoolExecutor(max_workers=2) as pool:
        results = list(pool.map(lambda case: _run(case[0], root, case[2]), BAD_INPUTS))
    return results, before, _listing(root)


def test_there_are_forty_kinds_of_bad_input():
    assert len(BAD_INPUTS) >= 40
    assert len({" ".join(args) + str(env) for args, _, env in BAD_INPUTS}) == len(BAD_INPUTS)


@pytest.mark.slow
@pytest.mark.parametrize(
    "index", range(len(BAD_INPUTS)), ids=[" ".join(c[0])[:60] for c in BAD_INPUTS]
)
def test_bad_input_is_one_line_and_exit_2(bad_input_results, index):
    results, _, _ = bad_input_results
    _, fragment, _ = BAD_INPUTS[index]
    result = results[index]
    lines = result.stderr.strip().splitlines()
    assert result.returncode == 2, result.stderr
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("glshade: error: ") and "Traceback" not in result.stderr
    assert fragment in lines[0], lines[0]
    assert result.stdout == ""


def test_bad_input_writes_nothing(bad_input_results):
    _, before, after = bad_input_results
    assert after == before
