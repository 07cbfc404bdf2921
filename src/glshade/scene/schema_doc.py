"""``docs/scene-format.md``, generated from the parameter schema (the registry).

Regenerate with ``python -m glshade.scene.schema_doc > docs/scene-format.md``; a test
keeps the file identical to what this module writes.
"""

from __future__ import annotations

from glshade.components.registry import Registry, registry
from glshade.params import Param

_INTRO = """# Scene files and parameters

A scene is a UTF-8 TOML file (a byte-order mark is tolerated; at most 1 MiB) with the
tables below. Every key is optional: a missing key takes the paper's default; an unknown
table or key is an error that names it. For example, the paper's cylinder seen from 15°
with a 3 µm deep dent:

```toml
[camera]
theta_deg = 15.0

[surface]
kind = "cylinder"
radius = 70.0

[defect]
dmax = 0.003    # mm
sigma2 = 4.0    # mm²
```

Every parameter can also be set on the command line of `glshade render`, `glshade
measure`, `glshade optimize` and `glshade view` by its dotted path, `--set
camera.theta_deg=15` (repeatable, applied after the file and the short flags), and the
ones with a short flag by that flag (`--theta 15`; not in `view`). `--set` also takes a
short name, the same in every command: a short flag without its dashes (`--set theta=15`,
`--set f-number=8`), a viewer slider's name (`--set stripe_sigma=0.1`) or a choice's key
(`--set outside=flat`); `-`, `_` and spaces are alike (`f_number`), and a name two
parameters declare (`black_level`: `black level`, the emitter's, or `black-level`, the
sensor's) is refused with both. Sweeps name their axes by the same paths. `--save-scene
SCENE.toml` on those commands writes the scene they used, every value resolved; loading it
back gives the same scene.

`--size N` resizes the scene the file (or the defaults) describes to N pixels across with
its field of view, by rescaling the pixel pitch; a camera value typed on the same command
line (`--set camera.pixel_pitch=0.01`, `--set camera.height=300`) is then kept as typed
and the field of view follows it, so `--set camera.pixel_pitch=0.01 --size 512` is the
scene of a file with `width = 512`, `height = 512` and `pixel_pitch = 0.01`. A typed
`camera.width` other than N is refused: the two conflict.

## How the scene is measured: `[measure]`

A scene file may also say how its scene is measured, in a `[measure]` table: `method =
"NAME"` (the instrument; default: the one its emitter is measured by) and that
instrument's settings (`docs/measure-settings.md`), each checked against its declaration
when the scene is measured:

```toml
[measure]
method = "pmd"
heights = "frankot-chellappa"
```

`glshade measure`, `glshade optimize`, the viewer's instrument views (`glshade view`) and
a snapshot test of the file (`glshade_snapshot.check("panel.toml")`) start from it, and a
sweep from its base file's;
the command line's flags and `--set measure.KEY=VALUE`, or the sweep file's own
`[measure]`, override it key by key, and `--method` another instrument than the table's
measures with that instrument's own settings (a warning says so). The table is the
file's, not the scene's: the scene, its case id and `--save-scene` are the same without
it, and `glshade render` (which measures nothing) does not read it.

## Units

A bare number is in the unit of its row: lengths in mm (a few in µm, as their row
says), areas in mm², angles in degrees, so `dmax = 5` is a 5 mm dent. Any number may carry
its unit instead, as a string in a scene file (`dmax = "5 um"`, `distance = "25.6 cm"`,
`theta_deg = "0.2 rad"`, `half_size = ["15 cm", 100]`, `wavelength_um = "550 nm"`), in
`Scene.with_value("defect.dmax", "5um")`, in a sweep's grid (a list or a range's `start`,
`stop` and `step`), and on the command line: `--dmax 5um`, `--set defect.sigma2=4mm2`,
`--theta 0.26rad`, `--dmaxs 3um,5um`, `--family defect.dmax=3um..5um`, `--over
camera.theta_deg=5deg..0.5rad`. A file written by glshade (`--save-scene`) holds bare
numbers. Where a row also accepts a word (`period = "auto"`, `exposure = "auto"`), its
allowed range says so. Lengths take `nm`, `um` (or `µm`), `mm`, `cm`, `m`; areas the same
followed by `2`, `^2` or `²`; angles `deg` (or `°`), `rad`, `mrad`; pixel counts `px`.
A unitless row (a formula's parameters, an f-number) takes bare numbers only. A value in
an unknown unit is refused with one line naming the key as it was typed, what the key
allows and how to write it with a unit.

Units are case-sensitive, as SI writes them: `0.005 Mm` would be 0.005 megametres, so it
is refused with one line (`did you mean mm? units are case-sensitive (Mm would be
megametres)`), and so are `MM`, `UM`, `DEG` or `Rad`; nothing is guessed. A number typed
as text, with or without its unit, is at most 64 characters long, blanks around it not
counted (room for a float's 17 digits, its exponent, a unit and blanks, several times
over); a longer one is refused with one line naming the limit, its length and its first
characters. The text is read in one pass, in time proportional to its length, whatever it
holds.

A formula surface's parameters (`parameters = { a = 0.002, b = 5.0 }`) can be set one by
one by their dotted path, the others kept: `--set surface.parameters.a=0.003`,
`Scene.with_value("surface.parameters.a", 0.003)`, a sweep axis
`"surface.parameters.a" = [0.001, 0.002]`, `--over surface.parameters.a=0..0.002`.

## Errors and warnings

A value outside its allowed range, a malformed or unreadable file, or an unknown key is
refused with one line naming the file or field, what was wrong and what is allowed, and
exit code 2; nothing is written. A value that is allowed but implausible (the *warned
beyond* of the allowed column: a dent deeper than 0.1 mm, a variance beyond 10⁴ mm², most
likely typed in the wrong unit) and a reflection lobe too wide for the stripes (see
`docs/physics.md`, *Glossy lobes and stripes*) print a `glshade: warning:` line, and the
run goes on.

*Role*: `feature` parameters pick shader code (a change may compile another program, once
per feature set); `uniform` parameters reach the shader as uniforms (a change never
recompiles; the defect's `dmax = 0` and an isotropic covariance also select simpler code,
which its features say). *Used by*: the component(s) that declare the parameter; a component is in
use when its table's selector names it (`surface.kind`, `render.reflection`) or when its
slot has only one component. A scene file written by glshade lists the parameters of the
components in use and any other that differs from its default.

This page is generated from the parameter declarations of the registered components, the
same declarations validation reads its ranges from
(`python -m glshade.scene.schema_doc > docs/scene-format.md`); a test keeps it current.
"""


def _allowed(reg: Registry, param: Param) -> str:
    text = param.allowed(reg.choices(param)).replace("|", "\\|")
    if param.plausible_max is not None:
        text += f"; warned beyond \\|{param.plausible_max:g}\\| {param.unit}".rstrip()
    return text + ("; may be unset" if param.default is None else "")


def _row(reg: Registry, param: Param) -> str:
    owners = reg.owners(param)
    used_by = ", ".join(f"{c.slot} `{c.name}`" for c in owners) or "selects the component"
    flag = f"`{param.flag}`" if param.flag else ""
    note = "" if param.stored else " (shorthand, not stored)"
    cells = [
        f"`{param.key}`",
        param.unit or "",
        f"`{param.default_text()}`",
        _allowed(reg, param),
        param.role,
        used_by,
        flag,
        param.doc + note,
    ]
    return "| " + " | ".join(cells) + " |"


def _components(reg: Registry) -> list[str]:
    lines = [
        "## Components",
        "",
        "| slot | table | selected by | components |",
        "|---|---|---|---|",
    ]
    for slot in reg.slots():
        selector = f"`{slot.selector.path}`" if slot.selector else "(one component)"
        names = "; ".join(f"`{c.name}`: {c.doc}" for c in reg.components(slot.name))
        lines.append(f"| {slot.name} | `[{slot.table}]` | {selector} | {names} |")
    return lines + [""]


def _component_docs(reg: Registry) -> list[str]:
    """Each component's own paragraph (its folder's ``docs.md``), by slot."""
    lines = []
    for component in reg.components():
        text = component.docs()
        if text:
            lines += [f"### {component.slot} `{component.name}`", "", text, ""]
    return ["## Components in detail", "", *lines] if lines else []


def scene_format_markdown(reg: Registry | None = None) -> str:
    """The whole page, from ``reg`` (default: the registry with the built-in components)."""
    reg = reg or registry()
    lines = [_INTRO, *_components(reg), *_component_docs(reg)]
    header = "| key | unit | default | allowed | role | used by | short flag | meaning |"
    for table in reg.tables():
        lines += [f"## `[{table}]`", "", header, "|---|---|---|---|---|---|---|---|"]
        lines += [_row(reg, p) for p in reg.table_params(table)]
        lines.append("")
    return "\n".join(lines)


if __name__ == "__main__":
    print(scene_format_markdown(), end="")
