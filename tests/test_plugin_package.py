"""A third-party plug-in, installed as a package: ``tests/plugins/glshade_paraboloid`` (a
surface kind, its GLSL and its oracle, found through the ``glshade.components`` entry
point) is installed into a virtual environment that sees this one's packages, and a
scene with it is measured from the CLI, rendered, and swept on a 2-worker Dask cluster
and in one process (the same table). The outer test process never installs it: it sees
no paraboloid, and meets the plug-in only to run the component contracts on it.
"""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest
from tests.plugin_venv import glshade_in, swept_here_and_on_dask, venv_with
from tests.test_components import check_absent_code, check_oracle, check_round_trip, check_uniforms

from glshade.components.registry import registry
from glshade.scene import paper_scene

PACKAGE = Path(__file__).parent / "plugins" / "glshade_paraboloid"


@pytest.fixture(scope="module")
def plugin_python(tmp_path_factory) -> Path:
    """The python of a fresh virtual environment with the plug-in package installed."""
    return venv_with(PACKAGE, tmp_path_factory.mktemp("plugin-venv"))


def test_the_cli_of_the_venv_measures_and_renders_the_plugin(plugin_python, tmp_path):
    scene = ["--size", "128", "--theta", "30", "--json"]
    done = glshade_in(plugin_python, "measure", "--surface", "paraboloid",
                      "--set", "surface.focal_radius=150", *scene)  # fmt: skip
    assert done.returncode == 0, done.stderr
    dome = json.loads(done.stdout)
    flat = json.loads(glshade_in(plugin_python, "measure", "--surface", "flat", *scene).stdout)
    # a convex base magnifies the emitter (the closed form of a dome of apex radius R)...
    assert dome["magnification"] > 1.0 and flat["magnification"] == 1.0
    # ... and the simulation sees it: the rays move less than on the flat plate
    assert 0.0 < dome["deflection_px"] < 0.95 * flat["deflection_px"]
    assert "paraboloid R 150 mm" in dome["scene"]
    out = tmp_path / "dome.png"
    args = ["--surface", "paraboloid", "--size", "64", "-o", str(out)]
    assert glshade_in(plugin_python, "render", *args).returncode == 0 and out.is_file()
    help_text = glshade_in(plugin_python, "render", "--help").stdout
    assert "paraboloid" in help_text and "--focal-radius" in help_text


def test_a_sweep_on_two_dask_workers_sees_the_plugin(plugin_python, tmp_path):
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(
        'size = 64\n[grid]\n"surface.kind" = ["flat", "paraboloid"]\n'
        '"camera.theta_deg" = [45.0, 20.0]\n"surface.focal_radius" = [120.0]\n'
    )
    tables = swept_here_and_on_dask(plugin_python, sweep, tmp_path)
    assert tables["dask"] == tables["local"]
    kinds = [row["surface.kind"] for row in tables["dask"]]
    assert kinds.count("paraboloid") == 2
    dome = [row for row in tables["dask"] if row["surface.kind"] == "paraboloid"]
    assert all(float(row["magnification"]) > 1.0 for row in dome)


def test_the_outer_process_does_not_see_it():
    assert "paraboloid" not in registry().names("surface")
    assert "surface.focal_radius" not in {p.path for p in registry().params()}


def _component():
    spec = importlib.util.spec_from_file_location(
        "glshade_paraboloid", PACKAGE / "glshade_paraboloid" / "__init__.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its table pickles and its dataclass resolves by name
    spec.loader.exec_module(module)
    return module.Paraboloid()


def test_the_plugin_meets_the_component_contracts(renderer, tmp_path):
    """Uniforms provided and used, GLSL against its oracle in fp32 and fp64, parameters
    round-tripping through TOML and --set, no code of it in another surface's shader."""
    with registry().registered(_component()) as paraboloid:
        check_uniforms(renderer, paraboloid)
        for precision in ("fp32", "fp64"):
            check_oracle(renderer, paraboloid, precision)
        check_round_trip(paraboloid, tmp_path)
        dome = paper_scene().with_size(16).with_value("surface.kind", "paraboloid")
        for scene in (dome, paper_scene("sphere").with_size(16)):
            check_absent_code(scene, ("image", "uv"))
    sys.modules.pop("glshade_paraboloid", None)
