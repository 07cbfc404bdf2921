"""Shader composition: a scene's features pick the GLSL files that go into its program.

The sources: the fragment template and the shared library (``lib/``) and slot headers
(``slots/``) under ``shaders/`` (shipped inside the wheel as ``glshade/shaders``), and
each component's own files in its folder. A Jinja2 environment with delimiters that
cannot clash with GLSL (``{$ … $}`` for blocks, ``{{ … }}`` for values) composes one
fragment shader per :class:`ShaderFeatures`; conditional includes keep unused code out
of the source itself, and an undefined template variable is an error, never a silent
default. Each component's files are found under a namespace of their own
(``<slot>.<name>/file.glsl``), so a plug-in's file never shadows a built-in one.

A slot's header (``slots/<slot>.glsl``) declares what its component must define; the
composer checks that the component's files define every function it declares and that
every uniform it provides is in its slot's namespace, each with one clear error naming
the component. Composition needs no GPU and is cached by feature set; the GL program
cache (in the renderer) uses the same key. Which files go in is the active components'
choice: the composer loops over them and knows no component by name. Everything that
changes continuously (θ, the phase, radii, dmax, σ²) is a uniform, so sweeping it never
recompiles.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Hashable, Iterable, Mapping
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

from glshade.cache import cache_dir
from glshade.components.base import Component, Slot, UniformContext
from glshade.components.registry import registry
from glshade.errors import GlshadeError, ShaderCompileError
from glshade.frame import OUTPUTS, Outputs, normalize_outputs
from glshade.scene import Scene

if TYPE_CHECKING:
    import jinja2

VERTEX_TEMPLATE = "fullscreen.vert.glsl"
FRAGMENT_TEMPLATE = "deflectometry.frag.glsl"
#: Names of shared library files start with this.
LIBRARY = "lib/"


@dataclass(frozen=True)
class ShaderFeatures:
    """What a program must contain; the key of the composition and program caches.

    ``components``: the component filling each slot, in composition order;
    ``variables``: the template variables they ask for (``(name, value)``, sorted:
    ``precision``, ``supersample``, ``defect``, ``cylinder_axis``, …); ``outputs``: the
    render targets, in canonical order. Two scenes with equal features share a program:
    everything else they differ in is a uniform.
    """

    components: tuple[Component, ...]
    variables: tuple[tuple[str, Hashable], ...]
    outputs: tuple[str, ...]

    @classmethod
    def from_scene(
        cls, scene: Scene, outputs: Outputs = ("image",), frame_count: int = 0
    ) -> ShaderFeatures:
        """The features of ``scene``'s program for ``outputs``; with the ``frames`` output,
        ``frame_count`` emitter frames per draw (the template variable ``frame_count``)."""
        wanted = normalize_outputs(outputs)
        variables = scene.active.features(scene)
        if "frames" in wanted:
            if frame_count < 1:
                raise GlshadeError("the frames output needs frame_count >= 1 frames per draw")
            if "image" in wanted:
                raise GlshadeError(
                    "the image and the frames outputs are two programs: render the image of "
                    "the scene showing a frame (EmitterComponent.showing), or the frames"
                )
            variables = {**variables, "frame_count": frame_count}
        return cls(
            components=scene.active.components,
            variables=tuple(sorted(variables.items())),
            outputs=tuple(name for name in OUTPUTS if name in wanted),
        )

    def template_variables(self) -> dict[str, object]:
        """The components' variables, ``outputs``, ``shading`` (a pixel value is computed:
        the image, or a stack of emitter frames) and ``patterns`` (how many patterns each ray
        is shaded for: the image's one, or the frames of a draw): what every GLSL file may
        use."""
        shading = "image" in self.outputs or "frames" in self.outputs
        return {
            **dict(self.variables),
            "outputs": self.outputs,
            "shading": shading,
            "patterns": self.frame_count or 1,
        }

    @property
    def frame_count(self) -> int:
        """Emitter frames per draw (0 without the ``frames`` output)."""
        count = dict(self.variables).get("frame_count", 0)
        return count if isinstance(count, int) else 0

    @property
    def precision(self) -> str:
        return str(dict(self.variables)["precision"])

    def selected(self) -> dict[str, str]:
        """Slot -> component name."""
        return {c.slot: c.name for c in self.components}


def shader_dir() -> Path:
    """The template, library and headers: inside the installed package, else
    ``shaders/`` of a checkout."""
    packaged = Path(str(resources.files("glshade"))) / "shaders"
    if packaged.is_dir():
        return packaged
    checkout = Path(__file__).resolve().parents[3] / "shaders"
    if checkout.is_dir():
        return checkout
    raise FileNotFoundError(
        f"glshade's GLSL sources are missing (looked in {packaged} and {checkout})"
    )


def namespace(component: Component) -> str:
    """The prefix under which a component's own GLSL files are found."""
    return f"{component.slot}.{component.name}"


def qualified(component: Component, name: str) -> str:
    """A file a component names, as the composer's loader finds it."""
    return name if name.startswith(LIBRARY) else f"{namespace(component)}/{name}"


#: The composer's Jinja options: delimiters that cannot clash with GLSL, and an undefined
#: variable is an error, never a silent default.
ENVIRONMENT_OPTIONS: dict[str, object] = {
    "block_start_string": "{$",
    "block_end_string": "$}",
    "variable_start_string": "{{",
    "variable_end_string": "}}",
    "comment_start_string": "{#",
    "comment_end_string": "#}",
    "trim_blocks": True,
    "lstrip_blocks": True,
    "keep_trailing_newline": True,
    "autoescape": False,
}


@functools.lru_cache(maxsize=16)
def _environment(folders: tuple[tuple[str, str], ...]) -> jinja2.Environment:
    """The environment whose loader finds the shaders directory's files and each
    component's under its namespace (``folders``: namespace, folder); its compiled
    templates are kept on disk between processes where the cache allows
    (:mod:`glshade.gpu.template_cache`)."""
    import jinja2  # imported here: a process that never compiles a program needs no Jinja

    mapping = {prefix: jinja2.FileSystemLoader(folder) for prefix, folder in folders}
    loader = jinja2.ChoiceLoader(
        [jinja2.FileSystemLoader(str(shader_dir())), jinja2.PrefixLoader(mapping, delimiter="/")]
    )
    return jinja2.Environment(
        loader=loader,
        undefined=jinja2.StrictUndefined,
        bytecode_cache=_template_cache(),
        **ENVIRONMENT_OPTIONS,  # type: ignore[arg-type]
    )


def _template_cache() -> jinja2.BytecodeCache | None:
    """The on-disk cache of compiled templates (its folder held open), or None where it
    is off (``GLSHADE_CACHE_DIR=`` or a relative path) or its folder cannot be used."""
    folder = cache_dir("templates")
    if folder is None:
        return None
    from glshade.gpu.template_cache import TemplateCache

    return TemplateCache(folder, {**ENVIRONMENT_OPTIONS, "undefined": "StrictUndefined"})


def environment_for(components: Iterable[Component]) -> jinja2.Environment:
    folders = tuple(sorted({(namespace(c), str(c.glsl_folder())) for c in components}))
    return _environment(folders)


def render_template(name: str, components: Iterable[Component] = (), **variables: object) -> str:
    """Compose one template (looked up in ``shaders/`` or a component's namespace); a
    variable the template uses but was not given raises."""
    return environment_for(components).get_template(name).render(**variables)


@dataclass(frozen=True)
class Stage:
    """One slot's part of the composed shader: its header and its component's files."""

    slot: Slot
    component: Component
    header: str | None
    files: tuple[str, ...]


def stages(features: ShaderFeatures) -> tuple[Stage, ...]:
    """Every slot's stage, in composition order; a file two components name (a library
    file) comes once, with the first."""
    variables = features.template_variables()
    seen: set[str] = set()
    out = []
    for component in features.components:
        slot = registry().slot(component.slot)
        files = []
        for name in component.glsl(variables):
            path = qualified(component, name)
            if path not in seen:
                seen.add(path)
                files.append(path)
        header = f"slots/{slot.header}" if slot.header else None
        out.append(Stage(slot, component, header, tuple(files)))
    return tuple(out)


@functools.lru_cache(maxsize=64)
def compose(features: ShaderFeatures) -> tuple[str, str]:
    """``(vertex_source, fragment_source)`` for a feature set (cached): the fragment
    template with the headers and files the active components name, nothing else. A
    component whose files do not define what its slot's header declares is an error."""
    parts = stages(features)
    check_contracts(features, parts)
    variables = features.template_variables()
    fragment = render_template(
        FRAGMENT_TEMPLATE,
        features.components,
        preamble=[f for s in parts if s.slot.preamble for f in s.files],
        preamble_headers=[s.header for s in parts if s.slot.preamble and s.header],
        stages=[s for s in parts if not s.slot.preamble],
        **variables,
    )
    # Blank lines left by removed blocks carry no meaning: squeeze runs of them.
    fragment = re.sub(r"\n{3,}", "\n\n", fragment)
    return render_template(VERTEX_TEMPLATE), fragment


# --------------------------------------------------------------------------- the viewer
#: What the viewer's display pass shades: the emitter's radiance at a traced map, in fp32.
DISPLAY_VARIABLES: dict[str, Hashable] = {
    "kernel": "none",
    "filtered": False,
    "diffuse": False,
    "precision": "fp32",
    "supersample": False,
}


def display_features(scene: Scene) -> ShaderFeatures:
    """The viewer's display pass for ``scene``: the render slot's preamble and the
    emitter's GLSL for the image (its ``emitter_radiance``)."""
    active = scene.active
    variables = {**active.emitter.features(scene), **DISPLAY_VARIABLES}
    return ShaderFeatures(
        (active.render, active.emitter), tuple(sorted(variables.items())), ("image",)
    )


@functools.lru_cache(maxsize=8)
def compose_display(features: ShaderFeatures) -> tuple[str, str]:
    """``(vertex_source, fragment_source)`` of the viewer's display pass."""
    parts = stages(features)
    check_contracts(features, parts)
    fragment = render_template(
        "viewer_display.frag.glsl",
        features.components,
        preamble=[f for s in parts if s.slot.preamble for f in s.files],
        stages=[s for s in parts if not s.slot.preamble],
        **features.template_variables(),
    )
    return render_template("viewer_display.vert.glsl"), fragment


def display_uniforms(scene: Scene, features: ShaderFeatures) -> dict[str, object]:
    """The emitter's uniforms of the display pass (float64 values)."""
    context = UniformContext(scene.local_origin(), features.template_variables(), None)
    return component_uniforms(scene, features, context)


# --------------------------------------------------------------------------- contracts
_PROTOTYPE = re.compile(r"^\s*\w+\s+(\w+)\s*\([^)]*\)\s*;", re.MULTILINE)


def required_functions(header: str, features: ShaderFeatures) -> tuple[str, ...]:
    """The functions a slot's header declares for these features."""
    text = render_template(header, features.components, **features.template_variables())
    return tuple(_PROTOTYPE.findall(text))


def check_contracts(features: ShaderFeatures, parts: tuple[Stage, ...]) -> None:
    """Every component's files define the functions its slot's header declares."""
    variables = features.template_variables()
    for stage in parts:
        if stage.header is None:
            continue
        source = "\n".join(
            render_template(f, features.components, **variables) for f in stage.files
        )
        missing = [
            name
            for name in required_functions(stage.header, features)
            if not re.search(rf"\b\w+\s+{name}\s*\([^;{{]*\)\s*\{{", source)
        ]
        if missing:
            raise GlshadeError(
                f"{stage.slot.name} component {stage.component.name!r}: its GLSL "
                f"({', '.join(stage.files) or 'none'}) must define {', '.join(missing)}, "
                f"as shaders/{stage.header} declares"
            )


def check_uniform_names(component: Component, values: Mapping[str, object], slot: Slot) -> None:
    """Every uniform (and texture) a component provides is in its slot's namespace."""
    for name in values:
        if not name.startswith((slot.uniform_prefix, slot.texture_prefix)):
            raise GlshadeError(
                f"{slot.name} component {component.name!r} provides uniform {name}, outside "
                f"its slot's namespace {slot.uniform_prefix}* (textures {slot.texture_prefix}*)"
            )


def component_uniforms(
    scene: Scene, features: ShaderFeatures, context: UniformContext
) -> dict[str, object]:
    """Every uniform the active components provide for ``features`` (float64 values):
    each in its component's namespace, none provided twice."""
    values: dict[str, object] = {}
    for component in features.components:
        provided = component.uniforms(scene, context)
        check_uniform_names(component, provided, registry().slot(component.slot))
        for name, value in provided.items():
            if name in values:
                raise ValueError(f"uniform {name} provided twice ({component!r})")
            values[name] = value
    return values


# --------------------------------------------------------------------------- errors
# Driver log formats: Mesa "0:12(5): error: …", NVIDIA "0(12) : error C0000: …",
# ANGLE/others "ERROR: 0:12: …".
_LINE_PATTERNS = (
    re.compile(r"^\s*\d+:(\d+)\(\d+\)"),
    re.compile(r"^\s*\d+\((\d+)\)\s*:"),
    re.compile(r"ERROR:\s*\d+:(\d+):"),
)


def error_lines(log: str) -> list[int]:
    """The 1-based source lines a driver's compile log points at, in order."""
    found: list[int] = []
    for entry in log.splitlines():
        for pattern in _LINE_PATTERNS:
            match = pattern.search(entry)
            if match:
                number = int(match.group(1))
                if number not in found:
                    found.append(number)
                break
    return found


def numbered_excerpt(source: str, line: int, context: int = 3) -> str:
    """Lines ``line - context … line + context`` of ``source``, numbered, the fault marked."""
    lines = source.splitlines()
    lo, hi = max(1, line - context), min(len(lines), line + context)
    width = len(str(hi))
    return "\n".join(
        f"{'>' if n == line else ' '} {n:>{width}} | {lines[n - 1]}" for n in range(lo, hi + 1)
    )


def compile_error(
    stage: str, log: str, source: str, features: ShaderFeatures | None = None
) -> ShaderCompileError:
    """A :class:`ShaderCompileError` that shows the driver's log and the numbered lines
    around each line it names."""
    parts = [
        f"GLSL {stage} shader failed to compile" + (f" for {features}" if features else "") + ":",
        log.strip(),
    ]
    for line in error_lines(log)[:3]:
        parts.append(numbered_excerpt(source, line))
    return ShaderCompileError("\n".join(parts))
