"""The snapshot plugin for users (``glshade_snapshot``), run by pytest's own ``pytester``:
a user's test file in a fresh folder, run in this process.

Each test writes a baseline with ``--glshade-update``, then changes what a change of
glshade, of the scene or of the driver would change (the stored image, a stored number,
the scene), and asserts what the run says: its outcome, its one-paragraph message, the
files and the HTML summary it leaves."""

from __future__ import annotations

import json
import os
import shutil
import textwrap
from pathlib import Path

import numpy as np
import pytest

from glshade.files import encode_png, read_png
from glshade.scene import Scene

pytest_plugins = ["pytester"]


@pytest.fixture(autouse=True, scope="module")
def _imported_here_first(tmp_path_factory):
    """Every module a snapshot check imports, imported in this process first: pytester
    runs the user's session in this process and drops the modules first imported there
    when it ends, and a second import of an extension module or of a class the registry
    keeps does not work. One PMD check and one summary, on GL and on the oracle, import
    them all."""
    from glshade.scene import paper_scene
    from glshade.snapshot.report import Entry, write_summary
    from glshade.snapshot.station import open_station

    example = Path(__file__).resolve().parents[1] / "examples" / "pmd_station.toml"
    for choice, size in (("gl", 32), ("oracle", 12)):
        station = open_station(choice)
        try:
            station.shoot(Scene.load(example).with_size(size))
            station.shoot(paper_scene("flat", 30.0, 4.0, 0.02).with_size(size))
        finally:
            station.release()
    entry = Entry("warm", "test", "passed", "", "renderer")
    write_summary(tmp_path_factory.mktemp("warm"), [entry], {"glshade": "warm"})


SCENE = 'paper_scene("flat", 30.0, 4.0, 0.02).with_size(64).updated(emitter={"period": "auto"})'


def user_file(marks: str = "", extra: str = "", scene: str = SCENE) -> str:
    """The user's test file: ``marks`` above the test, ``extra`` arguments to ``check``."""
    return "\n".join(
        [
            "import pytest",
            "from glshade.scene import paper_scene",
            "",
            marks,
            "def test_panel(glshade_snapshot):",
            f"    scene = {scene}",
            f'    glshade_snapshot.check(scene, name="panel"{extra})',
            "",
        ]
    )


def user_test(pytester: pytest.Pytester, marks: str = "", extra: str = "") -> Path:
    """The user's three-line test (with ``marks`` above it and ``extra`` arguments to
    ``check``) and an ini file: the baselines go to tests/glshade_snapshots."""
    pytester.makeini("[pytest]\n")
    return pytester.makepyfile(test_user=user_file(marks, extra))


def baseline_dir(pytester: pytest.Pytester) -> Path:
    return pytester.path / "tests" / "glshade_snapshots"


def updated(pytester: pytest.Pytester, *args: str) -> pytest.RunResult:
    result = pytester.runpytest("--glshade-update", *args)
    result.assert_outcomes(passed=1)
    return result


def paint_block(png: Path, value: float, rows=slice(20, 24), cols=slice(30, 34)) -> None:
    """Overwrite a 4x4 block of a stored 16-bit baseline image with ``value`` (of the
    peak): what a change of glshade or of the driver would do to 16 pixels."""
    pixels = read_png(png)
    pixels[rows, cols] = round(value * 65535)
    png.write_bytes(encode_png(pixels))


def edit_number(sidecar: Path, instrument: str, name: str, delta: float) -> float:
    data = json.loads(sidecar.read_text())
    data["numbers"][instrument][name] += delta
    sidecar.write_text(json.dumps(data))
    return data["numbers"][instrument][name]


# ------------------------------------------------------------------------------ outcomes
def test_update_writes_a_baseline_that_then_passes(pytester, renderer):
    user_test(pytester)
    result = updated(pytester)
    result.stdout.fnmatch_lines(["*glshade snapshots*", "1 written in *glshade_snapshots"])
    png, side = baseline_dir(pytester) / "panel.png", baseline_dir(pytester) / "panel.json"
    data = json.loads(side.read_text())
    assert data["format"] == "glshade-snapshot" and data["name"] == "panel"
    assert data["renderer"].startswith(renderer.context.info().renderer)
    assert data["precision"] == "fp32" and data["glshade"]
    assert data["scene"]["camera"]["theta_deg"] == 30.0
    assert data["scene"]["defect"]["dmax"] == 0.02
    assert data["image"]["width"] == 64 and data["image"]["bits"] == 16

    # the stored image and numbers are what glshade renders and measures of the scene
    from glshade.instruments.stripes.single import measure_scene
    from glshade.scene import paper_scene

    scene = eval(SCENE, {"paper_scene": paper_scene})
    image = renderer.render(scene, ("image",)).image.astype(np.float64)
    stored = read_png(png).astype(np.float64) / 65535 * data["image"]["scale"]
    assert np.abs(stored - image).max() <= 0.5 / 65535 * data["image"]["scale"] + 1e-7
    measured = measure_scene(renderer, scene)
    assert data["numbers"]["paper"]["visibility_px"] == measured.visibility_px > 0
    assert data["numbers"]["paper"]["status"] == "ok"
    assert "pmd" not in data["numbers"]  # stripes: the paper's numbers only

    first = png.read_bytes(), side.read_bytes()
    pytester.runpytest().assert_outcomes(passed=1)
    updated(pytester)  # rewriting an unchanged baseline leaves it byte for byte
    assert (png.read_bytes(), side.read_bytes()) == first


def test_missing_baseline_fails_with_the_command_that_creates_it(pytester):
    user_test(pytester)
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(
        [
            "*snapshot 'panel' has no baseline in *glshade_snapshots; create it with: "
            "pytest test_user.py::test_panel --glshade-update"
        ]
    )
    assert "Traceback" not in result.stdout.str()


def test_an_image_change_fails_naming_the_worst_pixel(pytester):
    user_test(pytester)
    updated(pytester)
    paint_block(baseline_dir(pytester) / "panel.png", 0.0)
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)
    text = result.stdout.str()
    assert "snapshot 'panel' moved: image:" in text
    # 16 pixels painted black; those that were not already dark are counted; the worst
    # is one of them, and no number moved
    found = _moved_pixels(text)
    assert 8 <= found["count"] <= 16
    assert 20 <= found["row"] < 24 and 30 <= found["col"] < 34
    assert found["expected"] == 0.0 and found["actual"] > 0.5
    assert "paper " not in text.split("moved:")[1].split("\n")[0]


def _moved_pixels(text: str) -> dict:
    import re

    found = re.search(
        r"image: (\d+) pixels differ by more than \S+ of the emitter's peak \((\d+) allowed\); "
        r"the worst, row (\d+) column (\d+): ([\d.]+) -> ([\d.]+)",
        text,
    )
    assert found is not None, text
    count, allowed, row, col = (int(found.group(i)) for i in range(1, 5))
    return {
        "count": count,
        "allowed": allowed,
        "row": row,
        "col": col,
        "expected": float(found.group(5)),
        "actual": float(found.group(6)),
    }


def test_a_number_change_alone_fails_naming_the_number(pytester):
    user_test(pytester)
    updated(pytester)
    side = baseline_dir(pytester) / "panel.json"
    edit_number(side, "paper", "visibility_continuous_px", 0.03)
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)
    line = next(x for x in result.stdout.lines if "snapshot 'panel' moved" in x)
    assert "image:" not in line
    assert "paper visibility_continuous_px" in line and "by -0.03 (tolerance 0.01 px)" in line

    # within the tolerance nothing moves: 0.004 px more is below 0.01 px
    edit_number(side, "paper", "visibility_continuous_px", -0.026)
    pytester.runpytest().assert_outcomes(passed=1)

    data = json.loads(side.read_text())
    data["numbers"]["paper"]["status"] = "edge"
    side.write_text(json.dumps(data))
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*paper status edge -> ok*"])


def test_a_scene_change_says_which_keys(pytester):
    user_test(pytester)
    updated(pytester)
    changed = user_file(scene=SCENE.replace("30.0", "31.0"))
    pytester.makepyfile(test_user=changed)
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(
        ["*snapshot 'panel' moved: image:*the scene is not the baseline's: camera.theta_deg 30.0"
         " -> 31.0*"]
    )  # fmt: skip


def test_update_rewrites_a_moved_baseline(pytester):
    user_test(pytester)
    updated(pytester)
    png = baseline_dir(pytester) / "panel.png"
    original = png.read_bytes()
    paint_block(png, 0.0)
    pytester.runpytest().assert_outcomes(failed=1)
    updated(pytester)
    assert png.read_bytes() == original
    pytester.runpytest().assert_outcomes(passed=1)


def test_unused_baselines_are_reported_and_fail_on_request(pytester):
    user_test(pytester)
    updated(pytester)
    folder = baseline_dir(pytester)
    for suffix in (".png", ".json"):
        (folder / f"old_panel{suffix}").write_bytes((folder / f"panel{suffix}").read_bytes())
    result = pytester.runpytest()
    result.assert_outcomes(passed=1)
    assert result.ret == 0
    result.stdout.fnmatch_lines(["1 unused baselines: old_panel; remove their .png and .json*"])

    result = pytester.runpytest("--glshade-fail-unused")
    result.assert_outcomes(passed=1)
    assert result.ret == pytest.ExitCode.TESTS_FAILED
    result.stdout.fnmatch_lines(["failed: 1 unused baselines: old_panel*"])

    result = pytester.runpytest("-k", "nothing_matches", "--glshade-fail-unused")
    assert result.ret == pytest.ExitCode.TESTS_FAILED  # both baselines unused, said so
    result.stdout.fnmatch_lines(["failed: 2 unused baselines (this run selected some tests*"])


def test_two_checks_of_one_name_are_refused(pytester):
    pytester.makeini("[pytest]\n")
    pytester.makepyfile(
        test_twice=f"""
        import pytest
        from glshade.scene import paper_scene

        @pytest.mark.parametrize("theta", [30.0, 40.0])
        def test_panel(glshade_snapshot, theta):
            glshade_snapshot.check({SCENE}.with_value("camera.theta_deg", theta), name="same")
        """
    )
    result = pytester.runpytest("--glshade-update")
    result.assert_outcomes(passed=1, failed=1)
    result.stdout.fnmatch_lines(
        ["*snapshot name 'same' is checked by test_twice.py::test_panel[[]30.0[]] already*"]
    )


# ------------------------------------------------------------------------------ the summary
def test_results_folder_keeps_the_images_and_an_html_summary(pytester):
    user_test(pytester)
    updated(pytester)
    paint_block(baseline_dir(pytester) / "panel.png", 0.0)
    edit_number(baseline_dir(pytester) / "panel.json", "paper", "deflection_px", 0.5)
    result = pytester.runpytest("--glshade-results", "out")
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*see *out/index.html*", "summary: *out/index.html"])
    out = pytester.path / "out"
    actual, expected = (
        read_png(out / "images/panel-actual.png"),
        read_png(out / "images/panel-expected.png"),
    )
    assert actual.dtype == np.uint16 and actual.shape == (64, 64)
    assert (expected[20:24, 30:34] == 0).all() and actual[20:24, 30:34].max() > 30000
    diff = read_png(out / "images/panel-diff.png")
    assert diff.shape == (64, 64, 3)
    brighter = diff[20:24, 30:34, 0]  # red: brighter now than the baseline
    assert brighter.max() == 255 and diff[..., 2].max() == 0  # nothing got darker
    assert np.count_nonzero(diff.any(axis=-1)) == np.count_nonzero(actual[20:24, 30:34] > 65)

    page = (out / "index.html").read_text()
    for needle in (
        "<title>glshade snapshots: 1 failed of 1</title>",
        'id="panel"',
        '<img src="images/panel-actual.png" alt="actual">',
        '<img src="images/panel-expected.png" alt="expected">',
        'src="images/panel-diff.png"',
        "deflection_px",
        "0.01 px",
        "theta_deg = 30.0",
        "dmax = 0.02",
        "test_user.py::test_panel",
    ):
        assert needle in page, needle
    row = page.split("<td>deflection_px</td>")[1].split("</tr>")[0]
    assert 'class="num"' in row and "0.01 px" in row
    assert '<tr class="moved"><td>paper</td><td>deflection_px</td>' in page


def test_html_summary_of_a_missing_baseline_shows_the_actual_image(pytester):
    user_test(pytester)
    result = pytester.runpytest("--glshade-results", "out")
    result.assert_outcomes(failed=1)
    page = (pytester.path / "out" / "index.html").read_text()
    assert "missing" in page and 'src="images/panel-actual.png"' in page
    assert not (pytester.path / "out" / "images" / "panel-diff.png").exists()


# ------------------------------------------------------------------------------ tolerances
@pytest.mark.parametrize(
    "marks, extra, outcome",
    [
        ("", "", "failed"),
        ("", ", image=6e-3", "passed"),
        ("", ", image_pixels=16", "passed"),
        ("pytestmark = pytest.mark.glshade_tolerance(image=6e-3)", "", "passed"),
        ("@pytest.mark.glshade_tolerance(image_pixels=16)", "", "passed"),
        ("pytestmark = pytest.mark.glshade_tolerance(image=6e-3)", ", image=1e-3", "failed"),
    ],
    ids=["default", "call", "call-pixels", "file", "test", "call-over-file"],
)
def test_tolerance_overrides(pytester, marks, extra, outcome):
    """A 4x4 block 5e-3 of the peak brighter: beyond the default 1e-3, within 6e-3 or 16
    pixels; the call's tolerance wins over the file's."""
    user_test(pytester, marks, extra)
    updated(pytester)
    png = baseline_dir(pytester) / "panel.png"
    pixels = read_png(png)
    pixels[20:24, 30:34] = np.clip(pixels[20:24, 30:34].astype(int) - round(5e-3 * 65535), 0, None)
    png.write_bytes(encode_png(pixels.astype(np.uint16)))
    pytester.runpytest().assert_outcomes(**{outcome: 1})


@pytest.mark.parametrize(
    "extra, needle",
    [
        (
            ", imag=1e-3",
            "check(): unknown tolerance 'imag'; the tolerances are image, image_pixels",
        ),
        (
            ", image=-1",
            "check(): image must be a number from 0 to 1 (of the emitter's peak), got -1",
        ),
        (", image_pixels=2.5", "check(): image_pixels must be a whole number"),
        (", name='../x'", "snapshot name '../x': must be 1 to 128 letters"),
    ],
)
def test_bad_arguments_are_one_line(pytester, extra, needle):
    text = user_file(extra=extra).replace('name="panel", name=', "name=")
    pytester.makeini("[pytest]\n")
    pytester.makepyfile(test_user=text)
    result = pytester.runpytest("--glshade-update")
    result.assert_outcomes(failed=1)
    assert needle in result.stdout.str()
    assert "Traceback" not in result.stdout.str()
    assert not baseline_dir(pytester).exists()


# ------------------------------------------------------------------------------ renderers
NO_GL = """
import glshade.gpu.renderer
from glshade.errors import ContextError

GL_RENDERER = glshade.gpu.renderer.Renderer.__init__


def refuse(self, *args, **kwargs):
    raise ContextError("no OpenGL context through EGL (test: forced)")


def pytest_configure(config):
    glshade.gpu.renderer.Renderer.__init__ = refuse


def pytest_unconfigure(config):  # the class outlives the run, in this process
    glshade.gpu.renderer.Renderer.__init__ = GL_RENDERER
"""


def test_without_opengl_the_oracle_compares_and_says_so(pytester):
    """A baseline made on llvmpipe, compared where no OpenGL context can be made: the
    NumPy float64 oracle renders and measures at the baseline's size, within the
    measured tolerance between the two, and the run says so."""
    user_test(pytester)
    updated(pytester)
    pytester.makeconftest(NO_GL)
    result = pytester.runpytest("-W", "default")
    result.assert_outcomes(passed=1)
    text = result.stdout.str()
    assert "renderer: NumPy float64 oracle" in text
    assert "no OpenGL: compared on the NumPy float64 oracle (no OpenGL context through EGL" in text
    assert "rendered and measured by the NumPy float64 oracle" in text  # the warning

    paint_block(baseline_dir(pytester) / "panel.png", 0.0)
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(
        ["*[[]baseline made on llvmpipe*, compared on NumPy float64 oracle (glshade *): tol*"]
    )

    # asked for OpenGL only, the run fails in one line instead
    result = pytester.runpytest("--glshade-renderer", "gl")
    result.assert_outcomes(errors=1)
    result.stdout.fnmatch_lines(
        ["*glshade snapshots: no OpenGL context through EGL (test: forced)*"]
    )


def test_the_oracle_on_request(pytester):
    user_test(pytester)
    updated(pytester)
    result = pytester.runpytest("--glshade-renderer", "oracle")
    result.assert_outcomes(passed=1)
    assert "renderer: NumPy float64 oracle" in result.stdout.str()
    assert "no OpenGL" not in result.stdout.str()


# ------------------------------------------------------------------------------ scene files
def test_a_scene_file_with_a_height_map_next_to_the_test(pytester):
    """The test names its scene file relative to itself; the file names its height map
    relative to itself; the sidecar names the map relative to the baseline folder."""
    x, z = np.meshgrid(np.linspace(-20, 20, 81), np.linspace(-20, 20, 81))
    np.save(pytester.path / "bump.npy", 0.002 * np.exp(-(x**2 + z**2) / 200.0))
    (pytester.path / "panel.toml").write_text(
        textwrap.dedent(
            """
            [camera]
            theta_deg = 40.0
            width = 64
            height = 64

            [emitter]
            period = "auto"

            [surface]
            kind = "heightmap"
            file = "bump.npy"
            spacing = [0.5, 0.5]
            outside = "flat"

            [defect]
            dmax = 0.01
            sigma2 = 4.0
            """
        )
    )
    pytester.makeini("[pytest]\n")
    sub = pytester.mkpydir("suite")
    (sub / "test_file.py").write_text(
        "def test_panel_file(glshade_snapshot):\n"
        "    glshade_snapshot.check('../panel.toml', name='panel_file')\n"
    )
    result = pytester.runpytest("--glshade-update")
    result.assert_outcomes(passed=1)
    data = json.loads((baseline_dir(pytester) / "panel_file.json").read_text())
    assert data["scene"]["surface"]["file"] == "../../bump.npy"
    stored = Scene.from_dict(data["scene"], base=baseline_dir(pytester)).to_dict()
    loaded = Scene.load(pytester.path / "panel.toml").to_dict()
    for tables in (stored, loaded):
        tables["surface"]["file"] = os.path.realpath(tables["surface"]["file"])
    assert stored == loaded
    pytester.runpytest().assert_outcomes(passed=1)

    # the map changes under the scene: the snapshot moves
    np.save(pytester.path / "bump.npy", 0.004 * np.exp(-(x**2 + z**2) / 200.0))
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*snapshot 'panel_file' moved: image:*"])


def test_a_fringe_scene_records_the_stations_numbers(pytester):
    """A scene whose screen shows fringes: the sidecar holds a phase-measuring station's
    numbers beside the paper's, compared in mm."""
    pytester.makeini("[pytest]\n")
    example = Path(__file__).resolve().parents[1] / "examples" / "pmd_station.toml"
    pytester.makepyfile(
        test_pmd=f"""
        from glshade.scene import Scene

        def test_station(glshade_snapshot):
            glshade_snapshot.check(Scene.load({str(example)!r}).with_size(64), name="station")
        """
    )
    pytester.runpytest("--glshade-update").assert_outcomes(passed=1)
    side = baseline_dir(pytester) / "station.json"
    data = json.loads(side.read_text())
    assert set(data["numbers"]) == {"paper", "pmd"}
    assert data["numbers"]["pmd"]["status"] == "ok" and data["numbers"]["pmd"]["pmd_shift_mm"] > 0
    pytester.runpytest().assert_outcomes(passed=1)
    edit_number(side, "pmd", "pmd_shift_mm", 0.001)
    result = pytester.runpytest()
    result.assert_outcomes(failed=1)
    result.stdout.fnmatch_lines(["*pmd pmd_shift_mm * mm, by -0.001 (tolerance 0.0002 mm)*"])


def test_the_example_folder_passes_as_committed(pytester, monkeypatch):
    """examples/snapshot_testing: a user's folder (its pytest.ini, scene file, tests and
    baselines) run from inside it, its scene's height map one folder up."""
    examples = Path(__file__).resolve().parents[1] / "examples"
    target = pytester.path / "examples"
    shutil.copytree(examples / "snapshot_testing", target / "snapshot_testing")
    shutil.copy(examples / "panel.x3p", target)
    monkeypatch.chdir(target / "snapshot_testing")
    result = pytester.runpytest()
    result.assert_outcomes(passed=3)
    result.stdout.fnmatch_lines(["3 passed in *examples/snapshot_testing/glshade_snapshots"])


def test_a_sensor_scene_stores_the_radiance_and_its_noise_floor(pytester, renderer):
    """With a sensor the stored image is the radiance that reaches it (two renderers draw
    different noise from radiances 1e-5 apart); the sensor's effect is in the numbers:
    its noise floor, compared in px. So a baseline made on GL passes on the oracle."""
    sensed = SCENE + '.updated(sensor={"full_well_e": 10000.0, "read_noise_e": 5.0})'
    pytester.makeini("[pytest]\n")
    pytester.makepyfile(test_user=user_file(scene=sensed))
    updated(pytester)
    data = json.loads((baseline_dir(pytester) / "panel.json").read_text())
    assert data["numbers"]["paper"]["noise_floor_px"] is not None

    from glshade.scene import paper_scene

    scene = eval(sensed, {"paper_scene": paper_scene})
    radiance = renderer.render(scene, ("image",), develop=False).image.astype(np.float64)
    recorded = renderer.render(scene, ("image",)).image.astype(np.float64)
    stored = read_png(baseline_dir(pytester) / "panel.png") / 65535 * data["image"]["scale"]
    assert np.abs(stored - radiance).max() < 1e-4
    assert np.abs(stored - recorded).max() > 1e-2  # the noisy record is not what is kept
    pytester.runpytest("--glshade-renderer", "oracle").assert_outcomes(passed=1)


def test_a_results_folder_that_is_a_file_is_a_usage_error(pytester):
    user_test(pytester)
    (pytester.path / "out").write_text("not a folder")
    result = pytester.runpytest("--glshade-results", "out")
    assert result.ret == pytest.ExitCode.USAGE_ERROR
    result.stderr.fnmatch_lines(["ERROR: --glshade-results out: is not a directory"])
    assert (pytester.path / "out").read_text() == "not a folder"
