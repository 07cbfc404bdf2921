"""The snapshot plugin's parts without pytest in the loop: a baseline's files, the
tolerances, and a shot against a baseline (images and numbers whose answer is known by
construction)."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from glshade.errors import GlshadeError
from glshade.snapshot import baseline as stored
from glshade.snapshot.compare import compare, number_changes, renderer_floor, scene_changes
from glshade.snapshot.station import Shot
from glshade.snapshot.tolerance import (
    ACROSS_RENDERERS,
    ACROSS_RENDERERS_FP64,
    DEFAULT,
    Tolerances,
)

LLVMPIPE = "llvmpipe (LLVM 15.0.6, 256 bits); 4.5 (Core Profile) Mesa 22.3.6"
NVIDIA = "NVIDIA H200/PCIe/SSE2; 4.5.0 NVIDIA 580.159.04"
NUMBERS = {
    "paper": {
        "visibility_px": 2.0,
        "visibility_continuous_px": 1.1451,
        "deflection_px": 1.1451,
        "folded": False,
        "best_phase_mm": 0.0,
        "status": "ok",
    }
}


def stripes(height=48, width=40) -> np.ndarray:
    rows = np.arange(height)[:, None] + 0.1 * np.arange(width)[None, :]
    return 0.5 + 0.5 * np.cos(rows / 3.0)


def make_baseline(tmp_path, image=None, renderer=LLVMPIPE, precision="fp32"):
    image = stripes() if image is None else image
    scene = {"camera": {"theta_deg": 30.0}, "defect": {"dmax": 0.004}}
    made = stored.Baseline("panel", image, NUMBERS, scene, renderer, precision, "0.1.0")
    made.write(tmp_path)
    return stored.read(tmp_path, "panel")


def test_a_baseline_reads_back_within_half_a_png_step(tmp_path):
    image = stripes()
    image[0, 0] = 1.00003  # a crest beyond the peak: the scale keeps it
    back = make_baseline(tmp_path, image)
    assert back.numbers == NUMBERS and back.renderer == LLVMPIPE
    assert back.scene["camera"]["theta_deg"] == 30.0
    assert np.abs(back.image - image).max() <= 0.5 * 1.00003 / 65535 + 1e-12
    side = json.loads((tmp_path / "panel.json").read_text())
    assert side["image"] == {
        "file": "panel.png", "width": 40, "height": 48, "bits": 16, "scale": 1.00003,
    }  # fmt: skip


def test_an_identical_shot_passes_at_zero_tolerance(tmp_path):
    """Storing rounds each pixel by up to half a 16-bit step: the comparison allows that
    much on top of the tolerance, so a shot identical to what was stored passes at 0."""
    back = make_baseline(tmp_path)
    zero = Tolerances(image=0.0, image_pixels=0, visibility_px=0.0, pmd_mm=0.0, pmd_um=0.0)
    result = compare("panel", back, Shot(stripes(), NUMBERS), zero, LLVMPIPE)
    assert result.passed and result.across == ""


def test_pixels_beyond_the_tolerance_are_counted_and_the_worst_named(tmp_path):
    back = make_baseline(tmp_path)
    moved = stripes()
    moved[10, 7] += 0.3
    moved[30:33, 5] -= 0.002  # three pixels just beyond 1e-3
    moved[40, 20] += 0.0009  # within it
    result = compare("panel", back, Shot(moved, NUMBERS), DEFAULT, LLVMPIPE)
    assert not result.passed
    assert result.image.beyond == 4 and result.image.worst == (10, 7)
    assert result.image.largest == pytest.approx(0.3, abs=1e-5)
    assert result.message().startswith(
        "snapshot 'panel' moved: image: 4 pixels differ by more than 0.001 of the emitter's "
        "peak (0 allowed); the worst, row 10 column 7: "
    )
    allowed = DEFAULT.with_overrides({"image_pixels": 4}, "test")
    assert compare("panel", back, Shot(moved, NUMBERS), allowed, LLVMPIPE).passed


def test_another_size_is_a_change(tmp_path):
    back = make_baseline(tmp_path)
    result = compare("panel", back, Shot(stripes(48, 41), NUMBERS), DEFAULT, LLVMPIPE)
    assert not result.passed
    assert "image is 41x48 pixels, its baseline 40x48" in result.message()


def test_numbers_compared_by_unit_and_status_by_word():
    now = json.loads(json.dumps(NUMBERS))
    now["paper"]["visibility_continuous_px"] += 0.01  # exactly the tolerance: within
    now["paper"]["deflection_px"] += 0.0101
    now["paper"]["best_phase_mm"] = 0.25  # recorded, not compared
    now["paper"]["folded"] = True  # recorded, not compared
    moved = [c for c in number_changes(NUMBERS, now, DEFAULT) if c.moved]
    assert [c.name for c in moved] == ["deflection_px"]
    now["paper"]["status"] = "edge"
    moved = [c for c in number_changes(NUMBERS, now, DEFAULT) if c.moved]
    assert [c.name for c in moved] == ["deflection_px", "status"]
    assert moved[1].describe() == "status ok -> edge"


def test_a_number_that_appears_or_vanishes_moved():
    now = json.loads(json.dumps(NUMBERS))
    now["paper"]["visibility_continuous_px"] = None
    [change] = [c for c in number_changes(NUMBERS, now, DEFAULT) if c.moved]
    assert change.name == "visibility_continuous_px"
    assert "1.1451 -> none px" in change.describe()


def test_a_stations_numbers_in_mm_and_its_depth_in_um():
    before = {"pmd": {"pmd_shift_mm": 0.79, "pmd_depth_um": 4.9, "status": "ok"}}
    now = {"pmd": {"pmd_shift_mm": 0.7903, "pmd_depth_um": 4.9002, "status": "ok"}}
    moved = {c.name: c for c in number_changes(before, now, DEFAULT) if c.moved}
    assert set(moved) == {"pmd_shift_mm"}  # 0.3 µm > 0.2 µm; depth 2e-4 µm: exactly within
    assert moved["pmd_shift_mm"].tolerance == pytest.approx(2e-4)
    depth = next(c for c in number_changes(before, now, DEFAULT) if c.name == "pmd_depth_um")
    assert depth.tolerance == pytest.approx(2e-4) and depth.unit == "µm"
    now["pmd"]["pmd_depth_um"] = 4.9003
    moved = {c.name: c for c in number_changes(before, now, DEFAULT) if c.moved}
    assert set(moved) == {"pmd_shift_mm", "pmd_depth_um"}
    assert "(tolerance 0.0002 µm)" in moved["pmd_depth_um"].describe()
    loose = DEFAULT.with_overrides({"pmd_um": 0.01}, "check()")
    assert not next(c for c in number_changes(before, now, loose) if c.name == "pmd_depth_um").moved


def test_a_dent_four_percent_deeper_fails_on_its_fitted_depth(_session_renderer):
    """The paper's dent at 5 µm, then 5.2 µm, measured by the snapshot's station on one
    renderer: the fitted depth moves by about 0.2 µm (which the former default, 0.2 µm,
    let pass on that number), a thousand times the default ``pmd_um``."""
    from glshade.scene import paper_scene
    from glshade.snapshot.station import measured_numbers

    scene = paper_scene("flat", 45.0, 4.0, 0.005).with_size(96)
    scene = scene.updated(emitter={"kind": "fringes"})
    before = measured_numbers(_session_renderer, scene)
    now = measured_numbers(_session_renderer, scene.updated(defect={"dmax": 0.0052}))
    assert before["pmd"]["status"] == now["pmd"]["status"] == "ok"
    change = now["pmd"]["pmd_depth_um"] - before["pmd"]["pmd_depth_um"]
    assert 0.15 < change <= 0.2
    moved = {c.name: c for c in number_changes(before, now, DEFAULT) if c.moved}
    assert "pmd_depth_um" in moved and moved["pmd_depth_um"].tolerance == DEFAULT.pmd_um
    assert change > 100 * DEFAULT.pmd_um


def test_another_renderer_raises_the_tolerances_to_the_measured_floor(tmp_path):
    floor, why = renderer_floor(LLVMPIPE, NVIDIA, "fp32")
    assert floor == ACROSS_RENDERERS and why.startswith(f"baseline made on {LLVMPIPE}, compared")
    floor, _ = renderer_floor(LLVMPIPE, "NumPy float64 oracle (glshade 0.1.0)", "fp64")
    assert floor == ACROSS_RENDERERS_FP64
    floor, _ = renderer_floor(LLVMPIPE, NVIDIA, "fp32", level_step=1 / 255)
    assert floor is not None and floor.image == pytest.approx(2e-4 + 1 / 255)
    assert renderer_floor(LLVMPIPE, LLVMPIPE, "fp32") == (None, "")

    back = make_baseline(tmp_path)
    moved = stripes()
    moved[5, 5] += 1.5e-4  # beyond a zero tolerance, within the renderers' floor
    zero = Tolerances(image=0.0, image_pixels=0, visibility_px=0.0, pmd_mm=0.0, pmd_um=0.0)
    assert not compare("panel", back, Shot(moved, NUMBERS), zero, LLVMPIPE).passed
    result = compare("panel", back, Shot(moved, NUMBERS), zero, NVIDIA)
    assert result.passed and result.tolerances.image == 2e-4


@pytest.mark.parametrize(
    "overrides, needle",
    [
        ({"imag": 1e-3}, "unknown tolerance 'imag'"),
        ({"image": -1e-3}, "image must be a number from 0 to 1"),
        ({"image": float("nan")}, "image must be a number from 0 to 1"),
        ({"image": True}, "image must be a number"),
        ({"image_pixels": 2.0}, "image_pixels must be a whole number"),
        ({"visibility_px": "0.1"}, "visibility_px must be a number"),
    ],
)
def test_bad_tolerances_are_one_line(overrides, needle):
    with pytest.raises(GlshadeError, match="^check\\(\\): ") as caught:
        DEFAULT.with_overrides(overrides, "check()")
    assert needle in str(caught.value) and "\n" not in str(caught.value)


def test_scene_changes_lists_the_keys():
    a = {"camera": {"theta_deg": 30.0}, "defect": {"dmax": 0.004}}
    b = {"camera": {"theta_deg": 35.0}, "defect": {"dmax": 0.004, "x0": 1.0}}
    assert scene_changes(a, b) == "camera.theta_deg 30.0 -> 35.0, defect.x0 unset -> 1.0"
    assert scene_changes(a, a) == ""


@pytest.mark.parametrize(
    "damage, needle",
    [
        (lambda p: p.with_suffix(".json").write_text("{"), "not JSON"),
        (lambda p: p.with_suffix(".json").write_text("[]"), "not a glshade snapshot sidecar"),
        (lambda p: _edit(p, format_version=9), "format version 9, this glshade reads 1"),
        (lambda p: _edit(p, renderer=3), "renderer missing or not a str"),
        (lambda p: _edit(p, image={"width": 40, "height": 0, "scale": 1}), "whole numbers"),
        (lambda p: _edit(p, image={"width": 41, "height": 48, "scale": 1}), "is 40x48"),
        (lambda p: p.with_suffix(".png").write_bytes(b"\x89PNG junk"), "not a 16-bit"),
        (lambda p: p.with_suffix(".png").unlink(), "does not exist"),
        (lambda p: _fifo(p.with_suffix(".json")), "is a FIFO"),
    ],
)
def test_a_damaged_baseline_is_one_line(tmp_path, damage, needle):
    make_baseline(tmp_path)
    damage(tmp_path / "panel.json")
    with pytest.raises(GlshadeError) as caught:
        stored.read(tmp_path, "panel")
    assert needle in str(caught.value) and "\n" not in str(caught.value)


def _edit(path, **changes):
    data = json.loads(path.read_text())
    data.update(changes)
    path.write_text(json.dumps(data))


def _fifo(path):
    path.unlink()
    os.mkfifo(path)


@pytest.mark.parametrize("name", ["", "../x", "a/b", ".hidden", "x" * 129, "a b", None, 3])
def test_names_are_file_names(name):
    with pytest.raises(GlshadeError, match="must be 1 to 128 letters"):
        stored.check_name(name)


def test_stored_names_are_the_sidecars(tmp_path):
    make_baseline(tmp_path)
    (tmp_path / "notes.txt").write_text("x")
    (tmp_path / "bad name.json").write_text("{}")
    assert stored.stored_names(tmp_path) == ["panel"]
    assert stored.stored_names(tmp_path / "missing") == []


def test_loading_the_plugin_loads_nothing_heavy():
    """pytest loads the plugin in every session of a project where glshade is installed:
    it must cost nothing until a test asks for the fixture."""
    import subprocess
    import sys

    heavy = ("numpy", "cv2", "moderngl", "jinja2", "glshade.scene", "glshade.gpu")
    code = f"import sys, glshade.snapshot.plugin; print([m for m in {heavy!r} if m in sys.modules])"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_the_summary_escapes_what_it_shows(tmp_path):
    """A path, a scene value or a message reaches the page as text, never as markup."""
    from glshade.snapshot.report import Entry, write_summary

    entry = Entry(
        "panel", "test_x.py::test<1>", "moved", "moved: <script>alert(1)</script>", "r&d",
        scene_toml='[surface]\nfile = "<b>.npy"\n',
    )  # fmt: skip
    page = write_summary(tmp_path, [entry], {"baselines": "/tmp/<i>"}).read_text()
    assert "<script>" not in page and "&lt;script&gt;alert(1)&lt;/script&gt;" in page
    assert "&lt;b&gt;.npy" in page and "/tmp/&lt;i&gt;" in page and "r&amp;d" in page
    assert "test_x.py::test&lt;1&gt;" in page


def test_under_xdist_no_process_judges_unused_baselines():
    from types import SimpleNamespace

    from glshade.snapshot.plugin import _distributed

    plain = SimpleNamespace(option=SimpleNamespace(dist="no"))
    controller = SimpleNamespace(option=SimpleNamespace(numprocesses=2, dist="load"))
    worker = SimpleNamespace(option=SimpleNamespace(), workerinput={"workerid": "gw0"})
    assert not _distributed(plain)
    assert _distributed(controller) and _distributed(worker)


def test_a_moved_number_says_when_its_status_makes_it_unreadable():
    """As the tables mark them: an edge status makes every paper number unreadable,
    unresolved stripes only visibility_px (the continuous numbers follow the rays)."""
    before = json.loads(json.dumps(NUMBERS))
    now = json.loads(json.dumps(NUMBERS))
    now["paper"].update(visibility_px=3.0, deflection_px=1.5, status="unresolved")
    moved = {c.name: c for c in number_changes(before, now, DEFAULT) if c.moved}
    assert moved["visibility_px"].unreadable == "unresolved"
    assert (
        "(tolerance 0.01 px, not readable: status unresolved)" in moved["visibility_px"].describe()
    )
    assert moved["deflection_px"].unreadable == ""
    now["paper"]["status"] = "edge"
    moved = {c.name: c for c in number_changes(before, now, DEFAULT) if c.moved}
    assert moved["deflection_px"].unreadable == "edge"
    pmd_before = {"pmd": {"pmd_shift_mm": 0.7, "decode_rms_mm": 1e-6, "status": "ok"}}
    pmd_now = {"pmd": {"pmd_shift_mm": 0.8, "decode_rms_mm": 1e-3, "status": "noise"}}
    moved = {c.name: c for c in number_changes(pmd_before, pmd_now, DEFAULT) if c.moved}
    assert moved["pmd_shift_mm"].unreadable == "noise"  # the dent's number
    assert moved["decode_rms_mm"].unreadable == ""  # the station's own stays readable


def test_a_scene_files_measure_table_sets_the_snapshots_settings(_session_renderer):
    """A snapshot of a scene file measures each instrument with the file's ``[measure]``
    settings where the table is its own (here the stripe metric's threshold), as
    ``glshade measure`` of that file does; another instrument keeps its defaults."""
    import glshade
    from glshade.instruments.record import Measurement
    from glshade.instruments.table import MeasureTable
    from glshade.metrics.visibility import MetricSettings
    from glshade.scene import paper_scene
    from glshade.snapshot.station import measured_numbers

    scene = paper_scene("flat", 45.0, 4.0, 0.005).with_size(256)
    table = MeasureTable("paper", True, {"threshold": 0.7})
    numbers = measured_numbers(_session_renderer, scene, table)["paper"]
    alone = glshade.measure(
        scene, renderer=_session_renderer, settings=MetricSettings(threshold=0.7)
    )
    expected = Measurement.of(scene, alone).row(("measured",))
    assert numbers == expected
    assert numbers != measured_numbers(_session_renderer, scene)["paper"]  # it mattered
    other = MeasureTable("pmd", True, {"heights": "frankot-chellappa"})
    assert measured_numbers(_session_renderer, scene, other) == measured_numbers(
        _session_renderer, scene
    )
