"""Shader composition: a scene's features pick the GLSL files that go into its program.

The sources live under ``shaders/`` (shipped inside the wheel as ``glshade/shaders``).
A Jinja2 environment with delimiters that cannot clash with GLSL (``{$ … $}`` for blocks,
``{{ … }}`` for values) composes one fragment shader per :class:`ShaderFeatures`;
conditional includes keep unused code out of the source itself, and an undefined
template variable is an error, never a silent default. Composition needs no GPU and is
cached by feature set; the GL program cache (in the renderer) uses the same key.

Everything that changes continuously (θ, the phase, radii, dmax, σ²) is a uniform, so
sweeping it never recompiles.
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import jinja2

from glshade.errors import ShaderCompileError
from glshade.frame import OUTPUTS, normalize_outputs
from glshade.scene import Scene

VERTEX_TEMPLATE = "fullscreen.vert.glsl"
FRAGMENT_TEMPLATE = "deflectometry.frag.glsl"


@dataclass(frozen=True)
class ShaderFeatures:
    """What a program must contain; the key of the composition and program caches.

    ``surface``: flat | cylinder | sphere; ``cylinder_axis``: z | x (cylinder only,
    else None); ``defect``: none | isotropic | full; ``reflection``: mirror |
    blinn_phong; ``precision``: fp32 | fp64; ``supersample``: more than one ray per
    pixel; ``outputs``: the render targets, in canonical order.
    """

    surface: str
    cylinder_axis: str | None
    defect: str
    reflection: str
    precision: str
    supersample: bool
    outputs: tuple[str, ...]

    @classmethod
    def from_scene(cls, scene: Scene, outputs=("image",)) -> ShaderFeatures:
        wanted = normalize_outputs(outputs)
        d = scene.defect
        defect = "none" if not d.present else ("isotropic" if d.isotropic else "full")
        return cls(
            surface=scene.surface.kind,
            cylinder_axis=scene.surface.axis if scene.surface.kind == "cylinder" else None,
            defect=defect,
            reflection=scene.render.reflection.replace("-", "_"),
            precision=scene.render.precision,
            supersample=scene.render.supersample > 1,
            outputs=tuple(name for name in OUTPUTS if name in wanted),
        )


def shader_dir() -> Path:
    """The GLSL sources: inside the installed package, else ``shaders/`` of a checkout."""
    packaged = Path(str(resources.files("glshade"))) / "shaders"
    if packaged.is_dir():
        return packaged
    checkout = Path(__file__).resolve().parents[3] / "shaders"
    if checkout.is_dir():
        return checkout
    raise FileNotFoundError(f"glshade's GLSL sources are missing (looked in {packaged} and {checkout})")


@functools.lru_cache(maxsize=None)
def _environment(directory: str) -> jinja2.Environment:
    return jinja2.Environment(
        loader=jinja2.FileSystemLoader(directory),
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


def render_template(name: str, **variables: object) -> str:
    """Compose one template; a variable the template uses but was not given raises."""
    return _environment(str(shader_dir())).get_template(name).render(**variables)


@functools.lru_cache(maxsize=64)
def compose(features: ShaderFeatures) -> tuple[str, str]:
    """``(vertex_source, fragment_source)`` for a feature set (cached)."""
    fragment = render_template(
        FRAGMENT_TEMPLATE,
        surface=features.surface,
        cylinder_axis=features.cylinder_axis,
        defect=features.defect,
        reflection=features.reflection,
        precision=features.precision,
        supersample=features.supersample,
        outputs=features.outputs,
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


def compile_error(stage: str, log: str, source: str, features: ShaderFeatures | None = None) -> ShaderCompileError:
    """A :class:`ShaderCompileError` that shows the driver's log and the numbered lines
    around each line it names."""
    parts = [f"GLSL {stage} shader failed to compile" + (f" for {features}" if features else "") + ":", log.strip()]
    for line in error_lines(log)[:3]:
        parts.append(numbered_excerpt(source, line))
    return ShaderCompileError("\n".join(parts))
