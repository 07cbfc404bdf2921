"""``docs/scene-format.md``, generated from the parameter schema (the registry).

Regenerate with ``python -m glshade.scene.schema_doc > docs/scene-format.md``; a test
keeps the file identical to what this module writes.
"""

from __future__ import annotations

from glshade.components.registry import Registry, registry
from glshade.scene.params import Param

_INTRO = """# Scene files and parameters

A scene is a TOML file with the tables below (SPEC §8). Every key is optional: a missing
key takes the paper's default; an unknown table or key is an error that names it. Every
parameter can also be set on the command line of `glshade render` and `glshade measure`
by its dotted path, `--set camera.theta_deg=15` (repeatable, applied after the file and
the short flags), and the ones with a short flag by that flag (`--theta 15`). Sweeps
name their axes by the same paths.

*Role*: `feature` parameters pick shader code (a change may compile another program, once
per feature set); `uniform` parameters reach the shader as uniforms (a change never
recompiles; the defect's `dmax = 0` and an isotropic covariance also select simpler code,
which its features say). *Used by*: the component(s) that declare the parameter; a component is in
use when its table's selector names it (`surface.kind`, `render.reflection`) or when its
slot has only one component. A scene file written by glshade lists the parameters of the
components in use and any other that differs from its default.

This page is generated from the parameter declarations of the registered components
(`python -m glshade.scene.schema_doc > docs/scene-format.md`); a test keeps it current.
"""


def _allowed(reg: Registry, param: Param) -> str:
    text = param.allowed(reg.choices(param)).replace("|", "\\|")
    return text + ("; may be unset" if param.default is None else "")


def _row(reg: Registry, param: Param) -> str:
    owners = reg.owners(param)
    used_by = ", ".join(f"{c.slot} `{c.name}`" for c in owners) or "selects the component"
    flag = f"`{param.flag}`" if param.flag else ""
    note = "" if param.stored else " (shorthand, not stored)"
    cells = [f"`{param.key}`", param.unit or "", f"`{param.default_text()}`", _allowed(reg, param),
             param.role, used_by, flag, param.doc + note]
    return "| " + " | ".join(cells) + " |"


def _components(reg: Registry) -> list[str]:
    lines = ["## Components", "", "| slot | table | selected by | components |", "|---|---|---|---|"]
    for slot in reg.slots():
        selector = f"`{slot.selector.path}`" if slot.selector else "(one component)"
        names = "; ".join(f"`{c.name}`: {c.doc}" for c in reg.components(slot.name))
        lines.append(f"| {slot.name} | `[{slot.table}]` | {selector} | {names} |")
    return lines + [""]


def scene_format_markdown(reg: Registry | None = None) -> str:
    """The whole page, from ``reg`` (default: the registry with the built-in components)."""
    reg = reg or registry()
    lines = [_INTRO, *_components(reg)]
    header = "| key | unit | default | allowed | role | used by | short flag | meaning |"
    for table in reg.tables():
        lines += [f"## `[{table}]`", "", header, "|---|---|---|---|---|---|---|---|"]
        lines += [_row(reg, p) for p in reg.table_params(table)]
        lines.append("")
    return "\n".join(lines)


if __name__ == "__main__":
    print(scene_format_markdown(), end="")
