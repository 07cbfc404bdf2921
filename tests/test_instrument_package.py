"""A third-party instrument, installed as a package: ``tests/plugins/glshade_brightness``
(the largest change in image brightness a dent makes, found through the
``glshade.instruments`` entry point) is installed into a virtual environment that sees
this one's packages, and is then used through every front end as glshade's own
instruments are: ``measure --method``, a sweep (in one process and on a 2-worker Dask
cluster: the same table), the optimiser's ``--metric`` and the snapshot plugin. Beside
it, ``tests/plugins/glshade_checkerboard``: an emitter whose pattern varies along both
screen coordinates, one package too, rendered by the GL shader and the float64 oracle
alike and measured by the instrument it names. The outer test process never installs
them: it knows two instruments and glshade's own emitters.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest
from tests.plugin_venv import glshade_in, swept_here_and_on_dask, venv_with

from glshade.instruments.registry import method_names

PLUGINS = Path(__file__).parent / "plugins"
PACKAGES = (PLUGINS / "glshade_brightness", PLUGINS / "glshade_checkerboard")

#: The checkerboard rendered by the GL shader and by the float64 oracle, in the plug-ins'
#: environment: the share of pixels they tell apart, the bright share, and the flips
#: between neighbouring pixels along the image's rows and columns.
BOARD = """
import json
import numpy as np
from glshade.gpu.renderer import Renderer
from glshade.oracle.renderer import OracleRenderer
from glshade.scene import Scene
scene = Scene().updated(emitter={"kind": "checkerboard", "cell": 20.0}, defect={"dmax": 0.0})
scene = scene.with_size(64)
with Renderer() as gl:
    shaded = gl.render(scene).image.astype(np.float64)
traced = OracleRenderer().render(scene).image
seen = np.isfinite(shaded) & np.isfinite(traced)
bright = traced > 0.5
print(json.dumps({
    "differ": float((np.abs(shaded - traced)[seen] > 0.5).mean()),
    "bright": float(bright[seen].mean()),
    "down": int(np.diff(bright, axis=0).sum()),
    "across": int(np.diff(bright, axis=1).sum()),
}))
"""


@pytest.fixture(scope="module")
def plugin_python(tmp_path_factory) -> Path:
    """The python of a fresh virtual environment with the plug-in packages installed."""
    return venv_with(PACKAGES, tmp_path_factory.mktemp("instrument-venv"))


def test_measure_names_and_measures_the_third_instrument(plugin_python):
    done = glshade_in(plugin_python, "measure", "--method", "brightness", "--size", "64", "--json")
    assert done.returncode == 0, done.stderr
    numbers = json.loads(done.stdout)
    # the paper's dent changes the stripes' brightness by a large share of the peak
    assert numbers["status"] == "ok" and 0.05 < numbers["brightness_change"] <= 1.0
    assert numbers["changed_pixels"] > 0
    flat = glshade_in(plugin_python, "measure", "--method", "brightness", "--size", "64",
                      "--set", "defect.dmax=0", "--json")  # fmt: skip
    assert json.loads(flat.stdout)["status"] == "outside"
    help_text = glshade_in(plugin_python, "measure", "--help").stdout
    assert "brightness" in help_text


def test_a_sweep_in_one_process_and_on_two_dask_workers(plugin_python, tmp_path):
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(
        'size = 48\n[metric]\nmethod = "brightness"\n[grid]\n'
        '"camera.theta_deg" = [60.0, 30.0]\n"defect.dmax" = [0.002, 0.01]\n'
    )
    tables = swept_here_and_on_dask(plugin_python, sweep, tmp_path)
    assert tables["dask"] == tables["local"] and len(tables["local"]) == 4
    for theta in ("60.0", "30.0"):
        shallow, deep = (
            float(row["brightness_change"])
            for row in tables["local"]
            if row["camera.theta_deg"] == theta
        )
        assert 0.0 < shallow <= deep  # a deeper dent changes the picture at least as much


def test_the_optimiser_aims_at_its_goal(plugin_python, tmp_path):
    done = glshade_in(plugin_python, "optimize", "--metric", "brightness_change",
                      "--over", "camera.theta_deg=20..80", "--size", "32", "--grid", "4",
                      "--refine", "4", "--json")  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    found = json.loads(done.stdout)
    assert (
        found["metric"] == "brightness_change"
        and 20.0 <= found["optimum"]["camera.theta_deg"] <= 80.0
    )
    assert 0.0 < found["brightness_change"] == found["value"]


def test_the_snapshot_plugin_compares_its_numbers(plugin_python, tmp_path):
    (tmp_path / "test_user.py").write_text(
        "from glshade.scene import paper_scene\n\n"
        "def test_panel(glshade_snapshot):\n"
        '    glshade_snapshot.check(paper_scene().with_size(48), name="panel")\n'
    )
    (tmp_path / "pytest.ini").write_text("[pytest]\n")
    pytest_in = [plugin_python, "-m", "pytest", "-q", "-p", "no:cacheprovider"]
    run = subprocess.run([*pytest_in, "--glshade-update"], cwd=tmp_path, capture_output=True,
                         text=True, timeout=300)  # fmt: skip
    assert run.returncode == 0, run.stdout[-3000:]
    side = tmp_path / "tests" / "glshade_snapshots" / "panel.json"
    stored = json.loads(side.read_text())
    assert stored["numbers"]["brightness"]["status"] == "ok"
    assert subprocess.run(pytest_in, cwd=tmp_path, capture_output=True, timeout=300).returncode == 0
    stored["numbers"]["brightness"]["brightness_change"] = 0.001  # a baseline far from now
    side.write_text(json.dumps(stored))
    moved = subprocess.run(pytest_in, cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert moved.returncode == 1 and "brightness_change" in moved.stdout


def test_the_outer_process_knows_two_instruments():
    assert method_names() == ("paper", "pmd")


def test_a_two_dimensional_emitter_is_one_package(plugin_python):
    """The checkerboard fills the emitter slot from its own package: the shader and the
    oracle agree on every pixel, its cells alternate down and across the image, and it is
    measured by the instrument it names (the brightness change at a cell's edge)."""
    board = subprocess.run(
        [plugin_python, "-c", BOARD], capture_output=True, text=True, timeout=300
    )
    assert board.returncode == 0, board.stderr[-3000:]
    found = json.loads(board.stdout)
    assert found["differ"] == 0.0 and 0.3 < found["bright"] < 0.7
    assert found["down"] > 0 and found["across"] > 0
    done = glshade_in(plugin_python, "measure", "--set", "emitter.kind=checkerboard",
                      "--set", "emitter.cell=3", "--size", "128", "--json")  # fmt: skip
    assert done.returncode == 0, done.stderr
    numbers = json.loads(done.stdout)
    assert numbers["status"] == "ok" and numbers["changed_pixels"] > 0
