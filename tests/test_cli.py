"""The ``glshade`` command: render, info, and one-line errors with exit code 2."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from glshade.app.cli import main
from glshade.files import read_png
from glshade.frame import AUTO_EXPOSURE_LEVEL, exposure_gain
from glshade.gpu.renderer import render
from glshade.scene import Scene, paper_scene


def run_cli(*args, env=None):
    return subprocess.run(
        [sys.executable, "-m", "glshade", *args],
        capture_output=True,
        text=True,
        env={**os.environ, **(env or {})},
        timeout=120,
    )


def test_render_writes_image_uv_and_scene(tmp_path, capsys):
    out, uv, saved = tmp_path / "img.png", tmp_path / "uv.npy", tmp_path / "scene.toml"
    code = main(
        [
            "render",
            "--surface",
            "sphere",
            "--theta",
            "30",
            "--sigma2",
            "9",
            "--dmax",
            "0.003",
            "--size",
            "64",
            "-o",
            str(out),
            "--uv",
            str(uv),
            "--save-scene",
            str(saved),
            "--bits",
            "16",
        ]
    )
    assert code == 0
    assert "wrote" in capsys.readouterr().out
    scene = Scene.load(saved)
    # a surface given by a flag takes the defaults a file naming only its kind gets (the
    # emitter's 2 mm period, not the paper's 10 mm for its sphere)
    typed = paper_scene("sphere", 30.0, 9.0, 0.003).with_size(64).updated(emitter={"period": 2})
    assert scene == typed
    expected = render(scene, ("image", "uv"))
    pixels = read_png(out)
    assert pixels.dtype == np.uint16 and pixels.shape == (64, 64)
    # written with the automatic exposure: the brightest point at 0.9 of the range
    exposed = expected.image * exposure_gain("auto", expected.image)
    assert np.nanmax(exposed) == pytest.approx(AUTO_EXPOSURE_LEVEL)
    np.testing.assert_allclose(pixels / 65535.0, np.clip(exposed, 0, 1), atol=1.0 / 65535)
    stored = np.load(uv)
    assert stored.dtype == np.float32 and stored.shape == (64, 64, 2)
    np.testing.assert_array_equal(stored, expected.uv)


def test_scene_file_with_flag_overrides(tmp_path):
    path = tmp_path / "s.toml"
    paper_scene("cylinder", 20.0).with_size(32).updated(surface={"radius": -40.0}).save(path)
    saved = tmp_path / "effective.toml"
    assert (
        main(
            [
                "render",
                str(path),
                "--theta",
                "60",
                "--phase",
                "0.5",
                "-o",
                str(tmp_path / "a.png"),
                "--save-scene",
                str(saved),
            ]
        )
        == 0
    )
    s = Scene.load(saved)
    assert s.camera.theta_deg == 60.0 and s.emitter.phase == 0.5
    assert s.surface.kind == "cylinder" and s.surface.radius == -40.0 and s.camera.width == 32


def test_info_reports_renderer_and_fp64():
    result = run_cli("info")
    assert result.returncode == 0, result.stderr
    assert "renderer:" in result.stdout and "fp64 shaders:     yes" in result.stdout


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["render", "--theta", "95"], "--theta (camera.theta_deg): must be in (0.001, 90)"),
        (["render", "--size", "0"], "--size (camera.width): must be an integer in [1, 16384]"),
        (
            ["render", "--surface", "sphere", "--radius", "0"],
            "--radius (surface.radius): must be non-zero",
        ),
        (["render", "--sigma2", "-1"], "--sigma2 (defect.sigma2): must be in (1e-06, 1e+08) mm²"),
        (["render", "--surface", "torus"], "invalid choice: 'torus'"),
        (["render", "missing.toml"], "scene file: must be an existing TOML file"),
        (
            ["render", "-o", "no/such/dir/x.png", "--size", "8"],
            "directory no/such/dir does not exist",
        ),
        (["render", "--set", "camera.zoom=2"], "camera.zoom: must be one of the keys"),
        (["render", "--set", "lens.f=2"], "lens: must be one of the tables"),
        (
            ["render", "--set", "camera.theta_deg=abc"],
            "camera.theta_deg: must be a number in degrees",
        ),
        (["render", "--set", "camera.theta_deg=90"], "camera.theta_deg: must be in (0.001, 90)"),
        (["render", "--set", "theta"], "expected NAME=VALUE"),
        (["render", "--set", "thta=5"], "--set thta: unknown setting; close matches: theta"),
        (
            ["render", "--set", "surface.kind=torus"],
            "surface.kind: must be one of flat, cylinder, sphere",
        ),
    ],
)
def test_bad_input_is_one_line_exit_2(tmp_path, args, fragment):
    result = subprocess.run(
        [sys.executable, "-m", "glshade", *args],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=120,
    )
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("glshade: error: ") and fragment in lines[0]
    assert "Traceback" not in result.stderr
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_set_any_parameter_by_its_path(tmp_path):
    saved = tmp_path / "scene.toml"
    code = main(
        [
            "render",
            "--theta",
            "30",
            "--set",
            "camera.theta_deg=20",
            "--set",
            "emitter.half_size=100,80",
            "--set",
            "defect.sigma_xz=0.5",
            "--set",
            "render.supersample=2",
            "--size",
            "16",
            "-o",
            str(tmp_path / "x.png"),
            "--save-scene",
            str(saved),
        ]
    )
    assert code == 0
    scene = Scene.load(saved)
    assert scene.camera.theta_deg == 20.0  # --set comes after the short flags
    assert scene.emitter.half_size == (100.0, 80.0) and scene.defect.sigma_xz == 0.5
    assert scene.render.supersample == 2


def test_unknown_key_in_scene_file(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text("[camera]\nzoom = 2.0\n")
    result = run_cli("render", str(path), "-o", str(tmp_path / "x.png"))
    assert result.returncode == 2
    assert "camera.zoom: must be one of the keys" in result.stderr
    assert not (tmp_path / "x.png").exists()


def test_missing_egl_names_the_debian_packages():
    result = run_cli("info", env={"GLSHADE_LIBEGL": "libEGL-that-does-not-exist.so"})
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr
    assert "libegl1" in result.stderr and "libgl1-mesa-dri" in result.stderr


def test_memory_budget_from_environment(tmp_path):
    result = run_cli("render", "-o", str(tmp_path / "x.png"), env={"GLSHADE_MEMORY_BUDGET_MB": "1"})
    assert result.returncode == 2
    assert (
        "camera.width x camera.height" in result.stderr
        and "memory budget of 1 MiB" in result.stderr
    )
    assert not (tmp_path / "x.png").exists()


def test_png_round_trip_keeps_the_channel_order(tmp_path):
    """Grey, RGB and RGBA images come back as written (OpenCV stores BGR(A))."""
    import numpy as np

    from glshade.files import encode_png

    rgb = np.zeros((2, 3, 3), np.uint8)
    rgb[..., 0] = 200  # red
    rgba = np.zeros((2, 3, 4), np.uint8)
    rgba[..., 2] = 90  # blue
    rgba[..., 3] = 255  # opaque
    for name, pixels in (("rgb.png", rgb), ("rgba.png", rgba), ("grey.png", rgb[..., 0])):
        (tmp_path / name).write_bytes(encode_png(pixels))
        assert np.array_equal(read_png(tmp_path / name), pixels), name
