"""``docs/measure-settings.md``: every registered instrument's settings, generated from
their declarations (``python -m glshade.instruments.settings_doc >
docs/measure-settings.md``; a test keeps the page current)."""

from __future__ import annotations

from glshade.instruments.registry import Instruments, instruments
from glshade.params import Param, declared_params
from glshade.run_settings import RunSettings

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

_RUN_INTRO = """## Run settings: where the cases run

Not how a case is measured but where and how fast: a run's worker processes or Dask
cluster, its analysis threads, the cases per Dask task and the EGL device, declared the
same way (`glshade.run_settings`). Their flags are on the commands that run
cases (`paper`, `sweep`, `optimize`; `--device` also on `render`, `measure`, `view`,
`info`), each with its declared default unless the command's help says otherwise
(`glshade paper --workers` defaults to `auto`); a value out of range is one line naming
the flag. What the machine can hold (two threads per CPU core, the workers the memory
budget holds) is checked when the run starts. They change no number: a case id never
depends on them.
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
    lines += [_RUN_INTRO, header, "|---|---|---|---|---|---|"]
    lines += [_row(declared) for declared in declared_params(RunSettings)]
    lines.append("")
    return "\n".join(lines)


if __name__ == "__main__":
    print(settings_markdown(), end="")
