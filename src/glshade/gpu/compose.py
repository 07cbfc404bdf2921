"""Shader composition: a scene's features pick the GLSL files that go into its program.

The sources live under ``shaders/`` (shipped inside the wheel as ``glshade/shaders``).
A Jinja2 environment with delimiters that cannot clash with GLSL (``{$ … $}`` for blocks,
``{{ … }}`` for values) composes one fragment shader per :class:`ShaderFeatures`;
conditional includes keep unused code out of the source itself, and an undefined
template variable is an error, never a silent default. Composition needs no GPU and is
cached by feature set; the GL program cache (in the renderer) uses the same key.

Which files go in is the active components' choice (:mod:`glshade.components`): the
composer loops over them and knows no component by name. Everything that changes
continuously (θ, the phase, radii, dmax, σ²) is a uniform, so sweeping it never
recompiles.
"""

from __future__ import annotations

import functools
import re
from collections.abc import Hashable
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import jinja2

from glshade.components.registry import registry
from glshade.errors import ShaderCompileError
from glshade.frame import OUTPUTS, normalize_outputs
from glshade.scene import Scene

VERTEX_TEMPLATE = "fullscreen.vert.glsl"
FRAGMENT_TEMPLATE = "deflectometry.frag.glsl"


@dataclass(frozen=True)
class ShaderFeatures:
    """What a program must contain; the key of the composition and program caches.

    ``components``: ``(slot, name)`` of the component filling each slot, in composition
    order; ``variables``: the template variables they ask for (``(name, value)``, sorted:
    ``precision``, ``supersample``, ``defect``, ``cylinder_axis``, …); ``outputs``: the
    render targets, in canonical order. Two scenes with equal features share a program:
    everything else they differ in is a uniform.
    """

    components: tuple[tuple[str, str], ...]
    variables: tuple[tuple[str, Hashable], ...]
    outputs: tuple[str, ...]

    @classmethod
    def from_scene(cls, scene: Scene, outputs=("image",)) -> ShaderFeatures:
        wanted = normalize_outputs(outputs)
        variables: dict[str, Hashable] = {}
        active = registry().active(scene)
        for component in active:
            for name, value in component.features(scene).items():
                if variables.setdefault(name, value) != value:
                    raise ValueError(f"template variable {name!r} set twice ({component!r})")
        return cls(
            components=tuple((c.slot, c.name) for c in active),
            variables=tuple(sorted(variables.items())),
            outputs=tuple(name for name in OUTPUTS if name in wanted),
        )

    def template_variables(self) -> dict[str, object]:
        """The components' variables and ``outputs``: what every GLSL file may use."""
        return {**dict(self.variables), "outputs": self.outputs}

    @property
    def precision(self) -> str:
        return dict(self.variables)["precision"]

    def selected(self) -> dict[str, str]:
        """Slot -> component name."""
        return dict(self.components)


def group_by_program(scenes, outputs=("image",)) -> dict[ShaderFeatures, list[int]]:
    """The indices of ``scenes`` grouped by the program they need (in first-seen order):
    a sweep worker that renders one group after another compiles each program once.
    Needs no GL context."""
    groups: dict[ShaderFeatures, list[int]] = {}
    for index, scene in enumerate(scenes):
        groups.setdefault(ShaderFeatures.from_scene(scene, outputs), []).append(index)
    return groups


def shader_dir() -> Path:
    """The GLSL sources: inside the installed package, else ``shaders/`` of a checkout."""
    packaged = Path(str(resources.files("glshade"))) / "shaders"
    if packaged.is_dir():
        return packaged
    checkout = Path(__file__).resolve().parents[3] / "shaders"
    if checkout.is_dir():
        return checkout
    raise FileNotFoundError(
        f"glshade's GLSL sources are missing (looked in {packaged} and {checkout})"
    )


@functools.cache
def _environment(directories: tuple[str, ...]) -> jinja2.Environment:
    return jinja2.Environment(
        loader=jinja2.FileSystemLoader(list(directories)),
        block_start_string="{$",
        block_end_string="$}",
        variable_start_string="{{",
        variable_end_string="}}",
        comment_start_string="{#",
        comment_end_string="#}",
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
        autoescape=False,
    )


def render_template(name: str, directories: tuple[str, ...] = (), **variables: object) -> str:
    """Compose one template (looked up in ``shaders/``, then ``directories``); a variable
    the template uses but was not given raises."""
    return _environment((str(shader_dir()), *directories)).get_template(name).render(**variables)


def component_files(
    features: ShaderFeatures,
) -> tuple[tuple[str, ...], tuple[str, ...], tuple[str, ...]]:
    """``(preamble, stages, directories)``: the GLSL files the active components name, in
    composition order (a file two of them name comes once), and where plug-ins keep theirs."""
    variables = features.template_variables()
    reg = registry()
    preambles = {slot.name for slot in reg.slots() if slot.preamble}
    preamble: list[str] = []
    stages: list[str] = []
    directories: list[str] = []
    for slot, name in features.components:
        component = reg.get(slot, name)
        if component.glsl_dir is not None and str(component.glsl_dir) not in directories:
            directories.append(str(component.glsl_dir))
        target = preamble if slot in preambles else stages
        target.extend(f for f in component.glsl(variables) if f not in target)
    return tuple(preamble), tuple(stages), tuple(directories)


@functools.lru_cache(maxsize=64)
def compose(features: ShaderFeatures) -> tuple[str, str]:
    """``(vertex_source, fragment_source)`` for a feature set (cached): the fragment
    template with the files the active components name, nothing else."""
    preamble, stages, directories = component_files(features)
    fragment = render_template(
        FRAGMENT_TEMPLATE,
        directories,
        preamble=preamble,
        stages=stages,
        **features.template_variables(),
    )
    # Blank lines left by removed blocks carry no meaning: squeeze runs of them.
    fragment = re.sub(r"\n{3,}", "\n\n", fragment)
    return render_template(VERTEX_TEMPLATE), fragment


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
