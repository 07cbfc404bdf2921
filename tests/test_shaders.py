"""Shader composition: only what a scene needs is in its source; caching; errors."""

from __future__ import annotations

import re
from dataclasses import replace

import jinja2
import pytest

import glshade.gpu.renderer as renderer_module
from glshade.errors import ShaderCompileError
from glshade.gpu.compose import (
    FRAGMENT_TEMPLATE,
    ShaderFeatures,
    compose,
    error_lines,
    numbered_excerpt,
    render_template,
)
from glshade.gpu.renderer import Renderer
from glshade.scene import Defect, RenderSettings, paper_scene

# Identifiers that only one feature's code declares.
MARKERS = {
    "flat": ["real base_height(real3 p) { return 0.0; }"],
    "curved": ["first_crossing("],
    "sphere": ["sphere_xz", "u_surface_axis_xz"],
    "cylinder": ["cyl_across", "u_surface_axis_off"],
    "cylinder_z": ["return p.x + u_surface_axis_off"],
    "cylinder_x": ["return p.z + u_surface_axis_off"],
    "dent": [
        "u_defect_dmax",
        "surface_gap",
        "u_defect_newton_iterations",
        "u_defect_march_steps",
        "real dent(",
    ],
    "isotropic": ["u_defect_inv_sigma2"],
    "full": ["u_defect_axis", "u_defect_inv_var"],
    "blinn_phong": ["u_reflection_shininess", "Blinn-Phong"],
    "fp64": ["double", "dvec3", "lf"],
    "supersample": ["u_render_supersample"],
    "image": ["out_image", "void shade(", "float stripes(", "u_emitter_sigma"],
    "uv": ["out_uv"],
    "mask": ["out_mask"],
    "distance": ["out_distance", "hit_distance"],
    "iterations": ["out_iterations", "g_evaluations"],
    "rays": ["out_rays", "loops_ran_whole", "u_pass_two"],
}


def source(scene, outputs=("image",)):
    return compose(ShaderFeatures.from_scene(scene, outputs))[1]


def absent(src, feature):
    return not any(marker in src for marker in MARKERS[feature])


def present(src, feature):
    return all(marker in src for marker in MARKERS[feature])


def test_flat_scene_has_no_curved_surface_code():
    src = source(paper_scene("flat"))
    assert present(src, "flat")
    assert absent(src, "sphere") and absent(src, "cylinder") and absent(src, "curved")
    assert "u_surface_radius" not in src


def test_sphere_scene_has_no_cylinder_or_flat_code():
    src = source(paper_scene("sphere"))
    assert present(src, "sphere") and present(src, "curved")
    assert absent(src, "cylinder") and absent(src, "flat")


@pytest.mark.parametrize("axis, other", [("z", "cylinder_x"), ("x", "cylinder_z")])
def test_cylinder_axis_code_only(axis, other):
    s = paper_scene("cylinder")
    src = source(replace(s, surface=replace(s.surface, axis=axis)))
    assert present(src, "cylinder") and present(src, f"cylinder_{axis}")
    assert absent(src, other) and absent(src, "sphere")


def test_no_defect_no_dent_code():
    src = source(paper_scene().without_defect())
    assert absent(src, "dent") and absent(src, "isotropic") and absent(src, "full")
    with_dent = source(paper_scene())
    assert present(with_dent, "dent")


def test_isotropic_and_full_covariance_are_exclusive():
    iso = source(paper_scene())
    full = source(replace(paper_scene(), defect=Defect(sigma_x2=4.0, sigma_z2=1.0, sigma_xz=0.5)))
    assert present(iso, "isotropic") and absent(iso, "full")
    assert present(full, "full") and absent(full, "isotropic")


def test_reflection_model_code_only():
    mirror = source(paper_scene())
    phong = source(replace(paper_scene(), render=RenderSettings(reflection="blinn-phong")))
    assert absent(mirror, "blinn_phong")
    assert present(phong, "blinn_phong")


def test_precision_code_only():
    fp32 = source(paper_scene())
    fp64 = source(replace(paper_scene(), render=RenderSettings(precision="fp64")))
    assert not re.search(r"\bdouble\b|\bdvec\d\b|\d+lf\b", fp32)
    assert "#define real double" in fp64 and "#define real float" not in fp64


def test_supersampling_code_only_when_asked():
    assert absent(source(paper_scene()), "supersample")
    assert present(
        source(replace(paper_scene(), render=RenderSettings(supersample=2))), "supersample"
    )


@pytest.mark.parametrize(
    "outputs",
    [
        ("image",),
        ("uv",),
        ("mask",),
        ("image", "uv"),
        ("uv", "mask"),
        ("image", "uv", "mask"),
        ("distance",),
        ("iterations",),
        ("image", "distance", "iterations"),
        ("rays",),
        ("image", "uv", "rays"),
    ],
)
def test_only_requested_outputs_are_declared(outputs):
    src = source(paper_scene(), outputs)
    for name in ("image", "uv", "mask", "distance", "iterations", "rays"):
        if name in outputs:
            assert present(src, name), name
        else:
            assert absent(src, name), name
    # locations are dense and in canonical order
    locations = [int(m) for m in re.findall(r"layout\(location = (\d+)\) out", src)]
    assert locations == list(range(len(outputs)))


def test_features_come_from_scene_values():
    f = ShaderFeatures.from_scene(paper_scene("cylinder", 5.0, 9.0, -0.002), ("uv", "image"))
    assert f.selected() == {
        "render": "sampling",
        "camera": "perspective",
        "surface": "cylinder",
        "defect": "gaussian",
        "emitter": "stripes",
        "reflection": "mirror",
        "fresnel": "none",
        "sensor": "linear",
        "part": "rigid",
    }
    assert dict(f.variables) == {
        "cylinder_axis": "z",
        "defect": "isotropic",
        "precision": "fp32",
        "supersample": False,
        "aperture": False,
        "distortion": False,
        "coherence": False,
        "kernel": "none",
        "filtered": False,
        "diffuse": False,
        "fresnel": False,
        "cover_glass": False,
        "screen_sag": False,
    }
    assert f.outputs == ("image", "uv")
    # theta, phase, sigma2, dmax (non-zero) are uniforms: same features
    g = ShaderFeatures.from_scene(
        paper_scene("cylinder", 45.0, 4.0, 0.005, phase=0.5), ("image", "uv")
    )
    assert f == g


def test_undefined_template_variable_raises():
    with pytest.raises(jinja2.UndefinedError):
        render_template(FRAGMENT_TEMPLATE, surface="flat")


def test_composition_is_cached_by_features():
    features = ShaderFeatures.from_scene(paper_scene("sphere"))
    assert compose(features) is compose(features)


def test_program_cache_theta_and_phase_are_uniforms(renderer):
    base = paper_scene("sphere").with_size(16)
    renderer.render(base)
    count = len(renderer._programs)
    program = renderer.program(ShaderFeatures.from_scene(base))
    for theta in (10.0, 30.0, 60.0):
        renderer.render(base.updated(camera={"theta_deg": theta}, emitter={"phase": theta / 100}))
    assert len(renderer._programs) == count
    assert renderer.program(ShaderFeatures.from_scene(base)) is program


def test_error_line_parsing():
    mesa = "0:12(5): error: syntax error, unexpected IDENTIFIER\n0:40(1): error: x"
    nvidia = "0(7) : error C0000: syntax error, unexpected identifier"
    assert error_lines(mesa) == [12, 40]
    assert error_lines(nvidia) == [7]
    text = numbered_excerpt("\n".join(f"line{i}" for i in range(1, 21)), 10, context=2)
    assert text.splitlines() == [
        "   8 | line8",
        "   9 | line9",
        "> 10 | line10",
        "  11 | line11",
        "  12 | line12",
    ]


def test_compile_error_shows_numbered_lines(gl_context, monkeypatch):
    vertex, fragment = compose(ShaderFeatures.from_scene(paper_scene()))
    lines = fragment.splitlines()
    fault = len(lines) - 3
    lines[fault - 1] = "    this is not GLSL;"
    broken = "\n".join(lines)
    monkeypatch.setattr(renderer_module, "compose", lambda features: (vertex, broken))
    with (
        Renderer(gl_context) as fresh,
        pytest.raises(ShaderCompileError) as info,
    ):  # empty program cache
        fresh.render(paper_scene().with_size(8))
    message = str(info.value)
    assert "fragment shader failed to compile" in message
    assert re.search(rf">\s*{fault} \|     this is not GLSL;", message), message
    assert f"{fault - 1} |" in message and f"{fault + 1} |" in message
