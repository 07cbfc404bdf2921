"""The component contract, parametrised over the registry: every registered component
(and a toy surface registered here, as a plug-in would be) must

- provide exactly the uniforms its GLSL keeps active (none missing, none dead);
- agree with its NumPy float64 oracle on random scenes, within the precision's tolerance
  (uv within 5e-4 mm in fp32 and 1e-6 mm in fp64, as ``test_oracle.py``);
- round-trip every parameter it declares through TOML and ``--set``;
- leave no code in a composed shader when it (or one of its features) is absent.

Adding a component adds its cases here without new test code.
"""

from __future__ import annotations

import functools
import math
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np
import pytest
from tests.plugins.surface_tilted import Tilted

from glshade.app import args, cli
from glshade.components.base import UniformContext
from glshade.components.registry import registry
from glshade.frame import OUTPUTS
from glshade.gpu.compose import ShaderFeatures, compose, environment_for, stages
from glshade.gpu.renderer import RootSolver, scene_uniforms
from glshade.oracle import tracer
from glshade.scene import Scene, paper_scene
from glshade.scene.schema_doc import scene_format_markdown

#: Every output a single frame has, and with a sequence emitter the frame stack too.
SINGLE = tuple(name for name in OUTPUTS if name != "frames")
OUTPUT_SETS = [("image",), ("uv", "mask"), SINGLE]
UV_TOL = {"fp32": 5e-4, "fp64": 1e-6}
VARIANTS = {
    "paper": lambda s: s,
    "no-defect": lambda s: s.without_defect(),
    "full-covariance": lambda s: s.updated(
        defect={"sigma_x2": 4.0, "sigma_z2": 1.0, "sigma_xz": 0.5}
    ),
    "fp64-supersampled": lambda s: s.updated(render={"precision": "fp64", "supersample": 2}),
    "axis-x-concave": lambda s: s.updated(surface={"axis": "x", "radius": -60.0}),
    # a real screen (the stripes keep none of it): cover glass, pixels, black level, room
    # light and a measured response
    "real-screen": lambda s: s.updated(
        emitter={
            "glass_thickness": 1.1,
            "pixel_pitch": 0.25,
            "fill_factor": 0.8,
            "black_level": 0.01,
            "ambient": 0.02,
            "response_file": sample_response(),
        }
    ),
}


def _slot(component):
    return next(slot for slot in registry().slots() if slot.name == component.slot)


@functools.cache
def sample_map(name: str = "map") -> str:
    """A smooth test height map (a gentle bowl with waves, 0.5 mm spacing, ±30 × ±50 mm)
    as .npy, for the parameters that need a file (one per process)."""
    x = np.arange(-30.0, 30.0 + 1e-9, 0.5)
    z = np.arange(-50.0, 50.0 + 1e-9, 0.5)
    xx, zz = np.meshgrid(x, z)
    heights = -(xx**2 + zz**2) / 4000.0 + 0.002 * np.sin(xx / 3.0) * np.cos(zz / 4.0)
    path = Path(tempfile.gettempdir()) / f"glshade-test-{name}-{os.getpid()}.npy"
    np.save(path, heights if name == "map" else heights[::-1])
    return str(path)


@functools.cache
def sample_response() -> str:
    """A measured screen response (an sRGB-like curve at 8-bit commanded values), for the
    parameters that read one (one per process)."""
    commanded = np.arange(256)
    displayed = 0.4 + 120.0 * (commanded / 255.0) ** 2.2
    path = Path(tempfile.gettempdir()) / f"glshade-test-response-{os.getpid()}.csv"
    lines = ["# commanded, luminance (cd/m2)"] + [
        f"{c}, {d:.5f}" for c, d in zip(commanded, displayed, strict=True)
    ]
    path.write_text("\n".join(lines) + "\n")
    return str(path)


#: Values other than the default for parameters that read a file of another kind.
OTHER_FILES = {"emitter.response_file": sample_response}
#: Parameters that only mean something with others set (a pose's keys with their mode).
COMPANIONS = {
    "camera.position": (("camera.pose", "look_at"),),
    "camera.rvec": (("camera.pose", "extrinsics"), ("camera.tvec", (0.0, 0.0, 200.0))),
    "camera.tvec": (("camera.pose", "extrinsics"), ("camera.rvec", (0.0, 3.0, 0.0))),
    "camera.pose": (),
    "emitter.centre": (("emitter.pose", "placed"),),
}
#: Values for parameters that have no usable default (a height map's file and spacing).
NEEDS_VALUE = {"surface.file": sample_map, "surface.spacing": lambda: (0.5, 0.5)}


def scenes_for(component, size: int = 12) -> dict[str, Scene]:
    """Scenes in which ``component`` fills its slot, one per variant."""
    base = paper_scene("flat", theta_deg=30.0).with_size(size)
    selector = _slot(component).selector
    needed = {p.table: {} for p in component.params}
    for param in component.params:
        if param.path in NEEDS_VALUE:
            needed[param.table][param.key] = NEEDS_VALUE[param.path]()
    if selector is not None:
        needed.setdefault(selector.table, {})[selector.key] = component.name
    base = base.updated(**{table: values for table, values in needed.items() if values})
    return {name: variant(base) for name, variant in VARIANTS.items()}


def ids(components):
    return [f"{c.slot}-{c.name}" for c in components]


COMPONENTS = registry().components()


# ------------------------------------------------------------------ the contracts
def output_sets(scene):
    """The output sets a scene's program is checked with: a sequence emitter's (the
    fringes) also with its frame stack."""
    sets = [(outputs, ()) for outputs in OUTPUT_SETS]
    if scene.emitter.kind == "fringes":
        frames = scene.active.emitter.sequence(scene)[:3]
        others = tuple(name for name in SINGLE if name != "image")  # the image: its own program
        sets += [(("frames",), frames), ((*others, "frames"), frames)]
    return sets


def check_uniforms(renderer, component) -> None:
    for scene in scenes_for(component).values():
        for outputs, frames in output_sets(scene):
            features = ShaderFeatures.from_scene(scene, outputs, len(frames))
            program = renderer.program(features)
            active = {
                name
                for name in program
                if hasattr(program[name], "value") and name.startswith("u_")
            }
            provided = scene_uniforms(scene, RootSolver(), features, frames)
            assert active <= set(provided), (
                f"{features.selected()}: not provided {active - set(provided)}"
            )
            context = UniformContext(
                scene.local_origin(), features.template_variables(), RootSolver(), frames
            )
            own = set(component.uniforms(scene, context))
            assert own <= active, (
                f"{component!r} provides uniforms its GLSL does not use: {own - active}"
            )


def _random_scene(component, rng, precision: str) -> Scene:
    scene = scenes_for(component, size=24)["paper"]
    dmax = rng.choice([-1.0, 1.0]) * rng.uniform(0.002, 0.008)
    return scene.updated(
        camera={"theta_deg": rng.uniform(10.0, 80.0)},
        emitter={"phase": rng.uniform(0.0, 2.0)},
        defect={
            "dmax": dmax,
            "sigma2": rng.uniform(1.0, 9.0),
            "x0": rng.uniform(-1, 1),
            "z0": rng.uniform(-1, 1),
        },
        render={"precision": precision},
    )


def check_oracle(renderer, component, precision: str, seed: int = 7) -> None:
    rng = np.random.default_rng(seed)
    for _ in range(2):
        scene = _random_scene(component, rng, precision)
        shader = renderer.render(scene, ("image", "uv", "mask"))
        oracle = tracer.trace(scene, ("image", "uv", "mask"))
        both = shader.mask & oracle.mask
        inner = cv2.erode(both.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
        assert (shader.mask != oracle.mask).sum() <= 2, scene.title()
        assert inner.sum() > 50, f"too few rays reach the emitter: {scene.title()}"
        error = np.abs(shader.uv - oracle.uv).max(axis=-1)[inner].max()
        assert error <= UV_TOL[precision], f"{scene.title()}: uv error {error:.3g} mm"
        if scene.active.reflection.mirror_only:
            assert (
                np.abs(shader.image - oracle.image)[inner].max()
                <= {"fp32": 2e-3, "fp64": 1e-5}[precision]
                # a quantised emitter: a ray on a level's edge may land one level apart
                + scene.active.emitter.radiance_step(scene)
            )


def _other_value(param):
    """A valid value other than the default."""
    choices = registry().choices(param) or param.choices
    if param.value_type == "choice":
        return next(c for c in choices if c != param.default)
    if param.path == "camera.intrinsics":  # a camera matrix: fx, fy > 0
        return (4800.0, 5100.0, 500.0, 530.0)
    if param.value_type == "integer":
        return param.default + 4 if param.path == "sensor.bit_depth" else param.default + 1
    if param.value_type == "pair":
        return (
            (0.5, 0.75)
            if param.default is None
            else (param.default[0] * 0.5, param.default[1] * 0.75)
        )
    if param.value_type == "vector" and not param.size:  # any length: the default, doubled
        return tuple(2.0 * number for number in param.default)
    if param.value_type == "vector":
        return tuple(0.01 * (k + 1) * (-1) ** k for k in range(param.size))
    if param.value_type == "names":
        return tuple(reversed(param.default))
    if param.path in OTHER_FILES:
        return OTHER_FILES[param.path]()
    if param.value_type == "path":
        return sample_map("flipped")
    if param.value_type == "text":
        return param.default + " + 0.0001*x"
    if param.value_type == "table":
        return (*param.default, ("spare", 0.5))
    if param.default is None or param.default in param.keywords:
        return 0.625 if param.lo is None or param.lo < 0.625 else 1.5 * param.lo
    if param.nonzero:
        return -0.5 * param.default
    if param.lo is not None and param.hi is not None:
        return 0.5 * (param.default + param.hi)
    return param.default * 1.5 if param.lo is not None else param.default + 1.25


def _as_text(value) -> str:
    if (
        isinstance(value, tuple) and value and isinstance(value[0], tuple)
    ):  # a table of named numbers
        return ",".join(f"{name}={number!r}" for name, number in value)
    return ",".join(f"{v!r}" for v in value) if isinstance(value, tuple) else str(value)


def check_round_trip(component, tmp_path) -> None:
    base = scenes_for(component)["paper"]
    for param in component.params:
        value = getattr(base, param.table).clamp(param.key, _other_value(param))
        companions = COMPANIONS.get(param.path, ())
        scene = base.with_values([*companions, (param.path, value)])
        assert scene.value(param.path) == value
        path = tmp_path / f"{param.table}-{param.key}.toml"
        scene.save(path)
        assert Scene.load(path) == scene, param.path
        parsed_path, parsed = args.parse_setting(f"{param.path}={_as_text(value)}")
        assert base.with_values([*companions, (parsed_path, parsed)]) == scene, param.path


def _unique_lines() -> dict[str, set[str]]:
    """Per GLSL file the composer can use (the template's, the library's, the slot
    headers' and every registered component's): its code lines no other file has."""
    env = environment_for(registry().components())
    files = {
        name: env.loader.get_source(env, name)[0]
        for name in env.list_templates(filter_func=lambda name: name.endswith(".glsl"))
    }
    lines = {
        name: {
            ln.strip()
            for ln in text.splitlines()
            if len(ln.strip()) > 12 and not ln.strip().startswith(("//", "{$", "{#"))
        }
        for name, text in files.items()
    }
    return {
        name: own - set().union(*(v for k, v in lines.items() if k != name))
        for name, own in lines.items()
    }


def check_absent_code(scene: Scene, outputs) -> None:
    features = ShaderFeatures.from_scene(scene, outputs)
    parts = stages(features)
    source = {line.strip() for line in compose(features)[1].splitlines()}
    named = {f for s in parts for f in (*s.files, *((s.header,) if s.header else ()))}
    for name, unique in _unique_lines().items():
        if name.startswith(("deflectometry.", "fullscreen.", "viewer_", "slots/")) or not unique:
            continue
        found = unique & source
        if name in named:
            assert found, f"{name} is named for {features.selected()} but absent"
        else:
            assert not found, (
                f"{name} is not needed by {features.selected()} but in its source: "
                f"{sorted(found)[:2]}"
            )


# ------------------------------------------------------------------ parametrised
@pytest.mark.parametrize("component", COMPONENTS, ids=ids(COMPONENTS))
def test_uniforms_provided_and_used(renderer, component):
    check_uniforms(renderer, component)


@pytest.mark.parametrize("precision", ["fp32", "fp64"])
@pytest.mark.parametrize("component", COMPONENTS, ids=ids(COMPONENTS))
def test_glsl_agrees_with_oracle(renderer, component, precision):
    check_oracle(renderer, component, precision)


@pytest.mark.parametrize("component", COMPONENTS, ids=ids(COMPONENTS))
def test_parameters_round_trip(component, tmp_path):
    check_round_trip(component, tmp_path)


@pytest.mark.parametrize("component", COMPONENTS, ids=ids(COMPONENTS))
def test_absent_features_leave_no_code(component):
    for scene in scenes_for(component).values():
        for outputs in OUTPUT_SETS:
            check_absent_code(scene, outputs)


def test_every_parameter_is_declared_once_with_a_unit_and_a_role():
    params = registry().params()
    assert len({p.path for p in params}) == len(params)
    for param in params:
        assert param.role in ("feature", "uniform") and param.doc, param.path
        assert (
            param.check(param.default, registry().choices(param)) == param.default
            or param.default is None
        )


def test_a_missing_uniform_is_an_error_not_a_zero(renderer):
    class Forgetful(Tilted):
        name = "forgetful"

        def uniforms(self, scene, context):
            return {"u_surface_slope": 0.0}  # u_surface_z0 forgotten

    with registry().registered(Forgetful()):
        scene = paper_scene().with_size(8).with_value("surface.kind", "forgetful")
        with pytest.raises(Exception, match="u_surface_z0"):
            renderer.render(scene)


def test_no_component_name_is_branched_on_outside_the_components():
    """``grep`` for ``== "cylinder"`` and friends: only components and the registry may
    know a component by its name."""
    names = {c.name for c in COMPONENTS}
    alternatives = "|".join(map(re.escape, names))
    pattern = re.compile(rf"""(==|!=)\s*["']({alternatives})["']""")
    root = Path(__file__).resolve().parents[1] / "src" / "glshade"
    offenders = [
        f"{path.relative_to(root)}:{n}"
        for path in root.rglob("*.py")
        if "components" not in path.parts
        for n, line in enumerate(path.read_text().splitlines(), 1)
        if pattern.search(line)
    ]
    assert not offenders, offenders


# ------------------------------------------------------------------ a plug-in
def test_a_toy_surface_plugs_in_without_touching_glshade(renderer, tmp_path):
    """A tilted plane, one module and one GLSL file under tests/plugins/: it renders,
    traces in the oracle, meets every contract, and appears in the schema, the docs and
    the CLI."""
    with registry().registered(Tilted()) as toy:
        scene = (
            paper_scene("flat", theta_deg=30.0).with_size(24).with_value("surface.kind", "tilted")
        )
        tilted = scene.with_value("surface.tilt_deg", 2.0)
        assert not np.array_equal(
            renderer.render(scene, ("uv",)).uv, renderer.render(tilted, ("uv",)).uv, equal_nan=True
        )
        check_uniforms(renderer, toy)
        for precision in ("fp32", "fp64"):
            check_oracle(renderer, toy, precision)
        check_round_trip(toy, tmp_path)
        for outputs in OUTPUT_SETS:
            check_absent_code(tilted, outputs)
        # a 2° tilt turns the mirror ray by 4°: the flat plane's closed form, checked
        v_flat = tracer.trace(scene.without_defect(), ("uv",)).uv[12, 12, 1]
        v_tilt = tracer.trace(tilted.without_defect(), ("uv",)).uv[12, 12, 1]
        assert abs(v_tilt - v_flat) > 256.0 * math.tan(math.radians(3.0))
        assert "surface.tilt_deg" in {p.path for p in registry().params()}
        from glshade.app.viewer.controls import apply_setting, controls, panel_params

        assert (
            "tilt" in controls()
            and "tilted" in apply_setting(scene, "surface", "tilted").surface.kind
        )
        assert (
            apply_setting(scene, "tilt", 25.0, slider=True).surface.tilt_deg == 10.0
        )  # clamped to its slider
        assert "surface.tilt_deg" in [p.path for p in panel_params(scene)]
        assert "surface.radius" not in [p.path for p in panel_params(scene)]
        assert "`tilt_deg`" in scene_format_markdown() and "`tilted`" in scene_format_markdown()
        out = tmp_path / "tilted.png"
        code = cli.main(
            [
                "render",
                "--surface",
                "tilted",
                "--set",
                "surface.tilt_deg=1.5",
                "--size",
                "16",
                "-o",
                str(out),
                "--save-scene",
                str(tmp_path / "tilted.toml"),
            ]
        )
        assert code == 0 and out.is_file()
        assert Scene.load(tmp_path / "tilted.toml").surface.tilt_deg == 1.5
    assert "tilted" not in registry().names("surface")
    assert Scene().surface == Scene().surface and not hasattr(Scene().surface, "tilt_deg")


def test_sweeps_group_cases_by_program():
    """A sweep over θ, σ², dmax and the surface: the engine measures the cases of one
    geometry together (one defect-free analysis each) and the geometries of one program
    next to each other (the program compiled once), whatever the number of cases. The
    paper's metric shades from the map, which the absent dent's width does not reach:
    every σ² shares one analysis; so does phase measuring's (its defect-free scene's dent
    shape is fixed: :func:`glshade.instruments.pmd.model.defect_free`)."""
    from glshade.instruments.base import Case
    from glshade.instruments.pmd.settings import PmdSettings
    from glshade.measure.engine import geometry_key, grouped, program_key
    from glshade.metrics.visibility import MetricSettings

    scenes = [
        paper_scene(surface, theta, sigma2, dmax)
        for surface in ("flat", "sphere")
        for theta in (5.0, 45.0)
        for sigma2 in (1.0, 4.0)
        for dmax in (0.0, 0.003, 0.005)
    ]
    cases = [Case(i, scene) for i, scene in enumerate(scenes)]
    stripes = MetricSettings()
    groups = grouped(cases, stripes)
    assert len(groups) == 4  # (flat, sphere) x θ
    assert len(grouped(cases, PmdSettings())) == 4  # (flat, sphere) x θ
    assert sorted(c.key for group in groups for c in group) == list(range(len(scenes)))
    for group in groups:
        assert len({geometry_key(c.scene, stripes) for c in group}) == 1
    order = [program_key(group[0].scene) for group in groups]
    runs = [key for i, key in enumerate(order) if i == 0 or key != order[i - 1]]
    assert len(runs) == len(set(runs)) == 2  # one run of geometries per surface's program


def test_the_trace_without_a_dent_reads_only_its_centre():
    """What lets the engine share one defect-free analysis between dents of every width
    (``map_baseline_key``): the scene without its dent has the same program, the same
    uniforms and the same emitter pattern whatever the absent dent's covariance; its
    centre (the local frame's origin) still counts."""
    from glshade.instruments.stripes.single import map_baseline_key

    for surface in ("flat", "cylinder", "sphere"):
        normals = [
            paper_scene(surface, 35.0, sigma2, dmax).without_defect()
            for sigma2, dmax in ((1.0, 0.003), (16.0, 0.005))
        ]
        features = [ShaderFeatures.from_scene(n, ("uv",)) for n in normals]
        assert features[0] == features[1]
        uniforms = [scene_uniforms(n, RootSolver(), features[0]) for n in normals]
        assert uniforms[0] == uniforms[1]
        patterns = [n.active.emitter.pattern(n) for n in normals]
        assert patterns[0] == patterns[1]
        assert map_baseline_key(normals[0]) == map_baseline_key(normals[1])
        moved = normals[0].with_value("defect.x0", 0.5)
        assert map_baseline_key(moved) != map_baseline_key(normals[0])
        assert scene_uniforms(moved, RootSolver(), features[0]) != uniforms[0]


def test_metrics_and_plans_import_without_gl():
    """Only glshade.gpu and glshade.app load moderngl."""
    code = (
        "import sys, glshade, glshade.metrics.visibility, glshade.measure.single, "
        "glshade.oracle.tracer, "
        "glshade.scene.schema_doc, glshade.metrics.physics, glshade.study.plan, "
        "glshade.study.store, "
        "glshade.study.findings, glshade.components.registry; "
        "glshade.components.registry.registry(); "
        "print('moderngl' in sys.modules)"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    )
    assert result.stdout.strip() == "False"


def test_scene_format_doc_is_generated_from_the_schema():
    doc = Path(__file__).resolve().parents[1] / "docs" / "scene-format.md"
    assert doc.read_text() == scene_format_markdown(), (
        "regenerate: python -m glshade.scene.schema_doc > docs/scene-format.md"
    )
