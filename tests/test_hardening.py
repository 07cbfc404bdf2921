"""Hardening: random input never escapes as a traceback, outputs are only
regular files, studies are locked and never mixed, units, long renders, the lobe warning.
"""

from __future__ import annotations

import io
import json
import math
import os
import re
import signal
import socket
import subprocess
import sys
import time
from contextlib import redirect_stderr
from pathlib import Path

import cv2
import numpy as np
import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from glshade.app.args import scene_from_args
from glshade.app.cli import build_parser, main
from glshade.components.registry import registry
from glshade.errors import GlshadeError, SceneError
from glshade.files import atomic_write_bytes, check_image_output, check_output, encode_image
from glshade.gpu import renderer as renderer_module
from glshade.oracle.advice import scene_warnings
from glshade.oracle.footprint import footprint_mm
from glshade.scene import Scene, paper_scene
from glshade.study.plan import StudyPlan
from glshade.study.run import run_study
from glshade.study.store import read_results_csv
from glshade.units import parse_quantity

ROOT = Path(__file__).resolve().parents[1]
FAST = settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)


def _one_line(exc: Exception) -> bool:
    text = str(exc)
    return bool(text.strip()) and "\n" not in text


# --------------------------------------------------------------------------- property tests
_KEYS = [(p.table, p.key) for p in registry().params()]
_VALUES = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**20), 10**20),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=12),
    st.lists(st.floats(-1e3, 1e3), max_size=3),
    st.dictionaries(st.text(max_size=4), st.integers(), max_size=2),
    st.sampled_from(["flat", "sphere", "cylinder", "x", "z", "fp64", "blinn-phong", "mirror"]),
)


@st.composite
def scene_documents(draw) -> dict:
    """Mostly well-formed scene tables with random (often wrong) values, plus stray
    tables and keys."""
    document: dict = {}
    for table, key in draw(st.lists(st.sampled_from(_KEYS), max_size=8)):
        value = draw(_VALUES)
        if value is not None:
            document.setdefault(table, {})[key] = value
    if draw(st.booleans()):
        document[draw(st.text(min_size=1, max_size=6))] = draw(
            st.one_of(_VALUES, st.just({"k": 1}))
        )
    return document


def _load_or_refuse(path: Path) -> None:
    try:
        scene = Scene.load(path)
    except GlshadeError as exc:
        assert _one_line(exc), repr(str(exc))
    else:
        assert isinstance(scene, Scene)


@FAST
@given(document=scene_documents())
def test_random_scene_documents_give_a_scene_or_one_line(tmp_path, document):
    path = tmp_path / "scene.toml"
    try:
        text = tomli_w.dumps(document)
    except (TypeError, ValueError):
        return  # not representable in TOML (None, a mixed list): nothing to load
    path.write_text(text)
    _load_or_refuse(path)


@FAST
@given(data=st.binary(max_size=300), cut=st.integers(0, 400), byte=st.integers(0, 255))
def test_random_and_mutated_bytes_give_a_scene_or_one_line(tmp_path, data, cut, byte):
    good = (ROOT / "docs" / "figures" / "paper_centre.toml").read_bytes()
    path = tmp_path / "scene.toml"
    for raw in (data, good[:cut] + bytes([byte]) + good[cut + 1 :], good[:cut]):
        path.write_bytes(raw)
        _load_or_refuse(path)


_FLAGS = [
    "--theta",
    "--dmax",
    "--sigma2",
    "--period",
    "--phase",
    "--radius",
    "--size",
    "--supersample",
    "--shininess",
    "--surface",
    "--axis",
    "--precision",
    "--reflection",
    "--set",
    "--bits",
    "-o",
    "--uv",
]
_WORDS = [
    "5",
    "-1",
    "0",
    "95",
    "nan",
    "inf",
    "1e400",
    "5um",
    "3mm2",
    "0.2rad",
    "abc",
    "",
    "=",
    "camera.theta_deg=5",
    "defect.dmax=5um",
    "emitter.half_size=1,2",
    "lens.f=1",
    "sphere",
    "torus",
    "x",
    "fp64",
    "blinn-phong",
    "16",
    "65536",
    "-",
    "--",
    "a.png",
]


@FAST
@given(
    argv=st.lists(
        st.one_of(st.sampled_from(_FLAGS), st.sampled_from(_WORDS), st.text(max_size=6)), max_size=8
    )
)
def test_random_argument_lists_give_a_scene_or_one_line(argv):
    stderr = io.StringIO()
    try:
        with redirect_stderr(stderr):
            args = build_parser().parse_args(["render", *argv])
        scene = scene_from_args(args)
    except SystemExit as exit_:
        assert exit_.code == 2
        lines = stderr.getvalue().strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("glshade: error: "), stderr.getvalue()
    except GlshadeError as exc:
        assert _one_line(exc), repr(str(exc))
    else:
        assert isinstance(scene, Scene)


# --------------------------------------------------------------------------- outputs
@pytest.mark.parametrize("kind", ["fifo", "directory", "socket"])
def test_special_files_are_never_written(tmp_path, kind):
    path = tmp_path / "target.png"
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "directory":
        path.mkdir()
    else:
        server = socket.socket(socket.AF_UNIX)
        server.bind(str(path))
    try:
        with pytest.raises(GlshadeError, match=f"is a {'FIFO' if kind == 'fifo' else kind}"):
            atomic_write_bytes(path, b"data")
        assert not path.is_file()
        assert sorted(p.name for p in tmp_path.iterdir()) == ["target.png"]  # no temporary left
    finally:
        if kind == "socket":
            server.close()


def test_a_symlink_is_written_through(tmp_path):
    target = tmp_path / "real.png"
    target.write_bytes(b"old")
    link = tmp_path / "link.png"
    link.symlink_to(target)
    atomic_write_bytes(link, b"new")
    assert link.is_symlink() and target.read_bytes() == b"new"
    os.mkfifo(tmp_path / "pipe")
    (tmp_path / "to_pipe.png").symlink_to(tmp_path / "pipe")
    with pytest.raises(GlshadeError, match="is a FIFO"):
        check_output(tmp_path / "to_pipe.png", "-o")


def write_image(path: Path, image: np.ndarray, bits: int = 8) -> None:
    """``image`` written as ``glshade render -o PATH --bits BITS`` writes it."""
    target = check_image_output(path, "-o", bits)
    atomic_write_bytes(path, encode_image(image, target.suffix, bits), "-o")


def test_image_format_follows_the_extension(tmp_path, renderer):
    image = renderer.render(paper_scene().with_size(48)).image
    write_image(tmp_path / "f.tif", image, bits=32)
    write_image(tmp_path / "i.tiff", image, bits=16)
    write_image(tmp_path / "p.png", image, bits=16)
    stored = cv2.imread(str(tmp_path / "f.tif"), cv2.IMREAD_UNCHANGED)
    assert stored.dtype == np.float32 and np.array_equal(stored, image)
    sixteen = cv2.imread(str(tmp_path / "i.tiff"), cv2.IMREAD_UNCHANGED)
    assert sixteen.dtype == np.uint16 and np.array_equal(
        sixteen, cv2.imread(str(tmp_path / "p.png"), -1)
    )
    assert (tmp_path / "p.png").read_bytes()[:4] == b"\x89PNG" and (
        tmp_path / "f.tif"
    ).read_bytes()[:2] == b"II"
    for name in ("x.jpg", "x.JPEG", "x.webp"):
        with pytest.raises(GlshadeError, match="lossy"):
            write_image(tmp_path / name, image)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["f.tif", "i.tiff", "p.png"]


def test_cli_writes_tiff_by_extension(tmp_path, capsys):
    out = tmp_path / "r.tif"
    assert main(["render", "--size", "32", "--bits", "32", "-o", str(out)]) == 0
    assert cv2.imread(str(out), cv2.IMREAD_UNCHANGED).dtype == np.float32


# --------------------------------------------------------------------------- studies
def _paper(out: Path, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.Popen(
        [sys.executable, "-m", "glshade", "paper", "--out", str(out), "--no-progress", *extra],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


@pytest.mark.slow
def test_a_second_study_on_the_same_directory_is_refused(tmp_path):
    out = tmp_path / "study"
    first = _paper(out, "--surfaces", "flat,cylinder", "--thetas", "85,45,5", "--size", "192")
    owner = out / ".glshade.lock.json"
    deadline = time.monotonic() + 60
    while not owner.exists() and first.poll() is None and time.monotonic() < deadline:
        time.sleep(0.05)
    second = _paper(out, "--surfaces", "flat,cylinder", "--thetas", "85,45,5", "--size", "192")
    _, err = second.communicate(timeout=60)
    _, first_err = first.communicate(timeout=300)
    assert first.returncode == 0, first_err
    assert second.returncode == 2 and len(err.strip().splitlines()) == 1, err
    assert re.search(
        rf"--out {re.escape(str(out))}: in use by 'glshade paper' \(pid {first.pid} on .+, since ",
        err,
    ), err
    rows = read_results_csv(out / "results.csv")
    assert (
        len(rows)
        == 2 * 3 * 8
        == len({(r.surface, r.theta_deg, r.sigma2_mm2, r.dmax_mm) for r in rows})
    )
    assert not owner.exists()
    # the lock died with its holder: a third run resumes everything
    third = _paper(out, "--surfaces", "flat,cylinder", "--thetas", "85,45,5", "--size", "192")
    out3, _ = third.communicate(timeout=120)
    assert third.returncode == 0 and "0 cases computed, 48 resumed" in out3


@pytest.mark.slow
def test_a_subset_rerun_is_refused_and_overwrite_removes_the_stale_files(tmp_path, capsys):
    out = tmp_path / "study"
    full = [
        "paper",
        "--out",
        str(out),
        "--no-progress",
        "--size",
        "64",
        "--thetas",
        "85,45,5",
        "--surfaces",
        "flat",
    ]
    assert main(full) == 0
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    assert "grid_flat_dmax3um.png" in before and len(read_results_csv(out / "results.csv")) == 24
    subset = [
        "paper",
        "--out",
        str(out),
        "--no-progress",
        "--size",
        "64",
        "--thetas",
        "85,45",
        "--surfaces",
        "flat",
        "--dmaxs",
        "5um",
    ]
    capsys.readouterr()
    assert main(subset) == 2
    err = capsys.readouterr().err.strip()
    assert (
        err.startswith(
            f"glshade: error: --out {out}: holds a study with another plan (dmaxs: 0.003,0.005 "
            "there, "
            "0.005 asked; thetas: 85,45,5 there, 85,45 asked)"
        )
        and "--overwrite" in err
    )
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before  # untouched
    assert main([*subset, "--overwrite"]) == 0
    rows = read_results_csv(out / "results.csv")
    assert sorted((r.theta_deg, r.dmax_mm) for r in rows) == sorted(
        (t, 0.005) for t in (85.0, 45.0) for _ in range(4)
    )
    names = {p.name for p in out.iterdir() if p.is_file()}
    assert (
        "grid_flat_dmax3um.png" not in names and "visibility_flat_dmax3um.png" not in names
    )  # stale: removed
    assert {"grid_flat_dmax5um.png", "visibility_flat_dmax5um.png", "report.md"} <= names
    assert "theta 5" not in (out / "report.md").read_text().replace(
        "theta 5 ", ""
    )  # only the new plan
    assert sorted(p.stem for p in (out / "cases").glob("*.json")) == sorted(
        f"flat_theta{t}_sigma2_{s}_dmax5um" for t in (85, 45) for s in (1, 4, 9, 16)
    )  # reused, not recomputed
    # the same plan again resumes without --overwrite
    assert main(subset) == 0 and "0 cases computed, 8 resumed" in capsys.readouterr().out


def test_other_settings_refused_then_replaced_wholesale(tmp_path):
    plan = StudyPlan(surfaces=("flat",), thetas=(45.0,), sigma2s=(4.0,), dmaxs=(0.005,), size=64)
    run_study(plan, tmp_path, progress=False)
    bigger = StudyPlan(surfaces=("flat",), thetas=(45.0,), sigma2s=(4.0,), dmaxs=(0.005,), size=96)
    with pytest.raises(GlshadeError, match="size: 64 there, 96 asked"):
        run_study(bigger, tmp_path, progress=False)
    result = run_study(bigger, tmp_path, progress=False, overwrite=True)
    assert result.computed == 1  # another size: the old case files were removed, not reused
    assert json.loads((tmp_path / "study.json").read_text())["size"] == 96


# --------------------------------------------------------------------------- units
@pytest.mark.parametrize(
    "text, unit, value",
    [
        ("5", "mm", 5.0),
        ("5um", "mm", 0.005),
        ("5 µm", "mm", 0.005),
        ("0.005mm", "mm", 0.005),
        ("2cm", "mm", 20.0),
        ("1e3nm", "mm", 1e-3),
        ("-3um", "mm", -0.003),
        ("4mm2", "mm²", 4.0),
        ("4e6um2", "mm²", 4.0),
        ("1cm^2", "mm²", 100.0),
        ("2mm²", "mm²", 2.0),
        ("15deg", "deg", 15.0),
        ("0.5rad", "deg", math.degrees(0.5)),
        ("64px", "px", 64.0),
        ("nan", "mm", math.nan),
    ],
)
def test_unit_parser(text, unit, value):
    got = parse_quantity(text, unit, "field")
    assert (math.isnan(got) and math.isnan(value)) or got == pytest.approx(value, rel=1e-12)


@pytest.mark.parametrize(
    "text, unit",
    [
        ("5xx", "mm"),
        ("5um", "deg"),
        ("5mm", "mm²"),
        ("4um2", "mm"),
        ("5mm", ""),
        ("", "mm"),
        ("um", "mm"),
        ("5 5", "mm"),
        ("1,5", "mm"),
    ],
)
def test_unit_parser_refuses(text, unit):
    with pytest.raises(SceneError, match=r"^field: must be a number") as info:
        parse_quantity(text, unit, "field")
    assert _one_line(info.value)


def test_units_on_the_command_line_and_the_implausible_warning(tmp_path, capsys):
    saved = tmp_path / "s.toml"
    assert (
        main(
            [
                "render",
                "--size",
                "16",
                "--dmax",
                "3um",
                "--set",
                "defect.sigma2=9e6um2",
                "-o",
                str(tmp_path / "a.png"),
                "--save-scene",
                str(saved),
            ]
        )
        == 0
    )
    scene = Scene.load(saved)
    assert scene.defect.dmax == pytest.approx(0.003) and scene.defect.sigma_x2 == pytest.approx(9.0)
    assert capsys.readouterr().err == ""
    assert (
        main(
            [
                "render",
                "--size",
                "16",
                "--dmax",
                "50",
                "--sigma2",
                "2e5",
                "-o",
                str(tmp_path / "b.png"),
            ]
        )
        == 0
    )
    warnings = capsys.readouterr().err.strip().splitlines()
    assert warnings == [
        (
            "glshade: warning: defect.dmax = 50 mm is beyond 0.1 mm (deeper than the shallow "
            "dents glshade simulates); "
            "values are in mm, write 5um for micrometres"
        ),
        (
            "glshade: warning: defect.sigma2 = 200000 mm² is beyond 10000 mm² (a dent over 100 mm "
            "wide); values are in "
            "mm², write 4um2 for µm²"
        ),
    ]


def test_study_titles_and_file_names_say_their_unit(tmp_path, capsys):
    assert (
        main(
            [
                "paper",
                "--out",
                str(tmp_path),
                "--no-progress",
                "--size",
                "48",
                "--thetas",
                "45,5",
                "--surfaces",
                "flat",
                "--sigma2s",
                "4",
                "--dmaxs",
                "3",
            ]
        )
        == 0
    )
    err = capsys.readouterr().err
    assert "glshade: warning: defect.dmax = 3 mm is beyond 0.1 mm" in err
    assert (tmp_path / "visibility_flat_dmax3000um.png").exists()
    assert paper_scene(dmax=0.003).title().endswith("dmax 3 µm")


# --------------------------------------------------------------------------- long renders
def test_banded_render_is_the_single_draw(renderer, monkeypatch):
    scene = paper_scene("sphere", theta_deg=20).with_size(96).updated(render={"supersample": 3})
    whole = renderer.render(scene, ("image", "uv", "mask"))
    monkeypatch.setattr(renderer_module, "SINGLE_DRAW_WORK", 500)  # bands of a few rows
    banded = renderer.render(scene, ("image", "uv", "mask"))
    assert np.array_equal(whole.image, banded.image)
    assert np.array_equal(whole.uv, banded.uv, equal_nan=True) and np.array_equal(
        whole.mask, banded.mask
    )


def test_ctrl_c_stops_a_long_render_within_seconds(tmp_path):
    """4096² at 16 x 16 rays takes over a minute on a CPU; SIGINT must end it promptly."""
    out = tmp_path / "big.png"
    process = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "glshade",
            "render",
            "--size",
            "4096",
            "--supersample",
            "16",
            "-o",
            str(out),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    time.sleep(4.0)  # past start-up, into the bands
    if process.poll() is not None:
        pytest.skip("the render finished within 4 s (a fast GPU): nothing to interrupt")
    sent = time.monotonic()
    process.send_signal(signal.SIGINT)
    _, err = process.communicate(timeout=60)
    took = time.monotonic() - sent
    assert process.returncode == 130, err
    assert err.strip().splitlines()[-1] == "glshade: interrupted"
    assert "row/s" not in err and "\r" not in err  # stderr is a pipe here: no progress bar
    assert took < 5.0, f"took {took:.1f} s to stop"  # loose: the bands aim at 0.25 s each
    assert not out.exists()


def test_work_budget_refuses_up_front(renderer):
    scene = paper_scene().with_size(64).updated(render={"supersample": 4})
    small = renderer_module.Renderer(renderer.context, max_rays=64 * 64 * 16 - 1)
    with pytest.raises(
        GlshadeError,
        match=r"64x64 pixels x 16 rays \(x 1 aperture and lobe samples\) = 6.55e\+04 rays, more "
        r"than the work budget",
    ):
        small.render(scene)
    small.release()


# --------------------------------------------------------------------------- lobes
def test_lobe_footprint_is_twice_the_lobe_times_the_distance():
    scene = (
        paper_scene()
    )  # flat, θ 45: the centre ray reflects into the emitter's centre, 256 mm away
    assert footprint_mm(scene, 1e-3) == pytest.approx(2 * 1e-3 * scene.emitter.distance, rel=1e-3)


def test_lobe_warning_and_a_default_that_shows_the_stripes(renderer):
    scene = paper_scene().with_size(128)
    assert scene_warnings(scene) == ()
    old = scene.updated(render={"reflection": "blinn-phong", "shininess": 1000.0})
    (line,) = scene_warnings(old)
    assert (
        line.startswith(
            "render.reflection = blinn-phong: the lobe spreads each point over 32.4 mm of the "
            "emitter, "
            "more than half the 2 mm stripe period"
        )
        and "render.shininess >= 1.05e+06" in line
    )
    default = scene.updated(render={"reflection": "blinn-phong"})
    assert scene_warnings(default) == ()
    assert scene_warnings(default.updated(render={"shininess": 1.1e6})) == ()
    assert len(scene_warnings(default.updated(render={"shininess": 1.0e6}))) == 1
    mirror = renderer.render(scene).image
    grey = renderer.render(old).image
    glossy = renderer.render(default).image
    assert np.ptp(grey) < 0.02  # the old default: one flat grey
    assert np.ptp(glossy) > 0.8 * np.ptp(mirror)  # the new one shows the stripes


# --------------------------------------------------------------------------- the format, documented
def test_the_scene_format_is_in_the_repository_and_linked(tmp_path):
    page = (ROOT / "docs" / "scene-format.md").read_text()
    assert "(docs/scene-format.md)" in (ROOT / "README.md").read_text()
    assert "SPEC" not in page
    parser = build_parser()
    render_help = parser._subparsers._group_actions[0].choices["render"].format_help()
    assert "docs/scene-format.md" in " ".join(render_help.split())
    example = re.search(r"```toml\n(.*?)```", page, re.DOTALL).group(1)
    path = tmp_path / "example.toml"
    path.write_text(example)
    scene = Scene.load(path)
    assert (scene.surface.kind, scene.camera.theta_deg, scene.defect.dmax) == (
        "cylinder",
        15.0,
        0.003,
    )


def test_measure_refuses_bad_input_before_rendering(tmp_path):
    import glshade

    bad = tmp_path / "bad.toml"
    bad.write_bytes(b"[defect]\ndmax = 0.005\n# \xff\n")
    for scene, fragment in (
        (tmp_path / "missing.toml", "scene file: must be an existing TOML file"),
        (bad, "must be UTF-8 text (byte 0xff on line 3"),
        (42, "scene: must be a glshade Scene or the path of a scene file, got int"),
    ):
        with pytest.raises(GlshadeError, match=re.escape(fragment)) as info:
            glshade.measure(scene)
        assert _one_line(info.value)
    os.mkfifo(tmp_path / "fifo.png")
    for overlay, fragment in (("o.jpg", "lossy"), (tmp_path / "fifo.png", "is a FIFO")):
        with pytest.raises(GlshadeError, match=fragment):
            glshade.measure(
                paper_scene().with_size(32), overlay=overlay, renderer=object()
            )  # never reaches it
