"""``docs/measure-settings.md``: every registered instrument's settings, generated from
their declarations (``python -m glshade.instruments.settings_doc >
docs/measure-settings.md``; a test keeps the page current)."""

from __future__ import annotations

from glshade.instruments.registry import Instruments, instruments
from glshade.params import Param, declared_params

_INTRO = """# Instrument settings

How each instrument measures: its settings, declared once with their unit, default and
range. The same declarations give the command line's short flags (`glshade measure`,
`optimize`, `paper`), `--set measure.KEY=VALUE`, the `[measure]` table of a scene file
or a sweep file (`method = "NAME"` and that instrument's keys; the command line and a
sweep's table override a scene file's key by key), a sweep's `measure.KEY` axes
(`"measure.threshold" = [0.3, 0.5]`) and the one-line errors that name a bad value. A
setting of another instrument than the one measuring is refused in one line.

This page is generated from those declarations
(`python -m glshade.instruments.settings_doc > docs/measure-settings.md`); a test keeps
it current.
"""


def _row(declared: Param) -> str:
    allowed = declared.allowed().replace("|", "\\|")
    if declared.default is None:
        allowed += "; may be unset"
    cells = [
        f"`{declared.key}`",
        declared.unit,
        f"`{declared.default_text()}`",
        allowed,
        f"`{declared.flag}`" if declared.flag else "",
        declared.doc,
    ]
    return "| " + " | ".join(cells) + " |"


def settings_markdown(found: Instruments | None = None) -> str:
    """The whole page, from ``found`` (default: the registered instruments)."""
    found = found or instruments()
    lines = [_INTRO]
    header = "| key | unit | default | allowed | short flag | meaning |"
    for name, item in found.by_name.items():
        lines += [f"## `{name}`: {item.title}", "", header, "|---|---|---|---|---|---|"]
        lines += [_row(declared) for declared in declared_params(item.settings_type)]
        lines.append("")
    return "\n".join(lines)


if __name__ == "__main__":
    print(settings_markdown(), end="")
