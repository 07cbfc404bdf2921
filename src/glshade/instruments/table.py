"""A file's ``[measure]`` table: which instrument measures a scene and its settings, as a
scene file or a sweep file writes them (docs/measure-settings.md).

``method`` names the instrument (default: the one the scene's emitter is measured by);
every other key is one of that instrument's declared ``measure.*`` settings, checked
against its declaration. A scene file's table is the scene's own: ``glshade measure``,
``optimize`` and ``sweep`` start from it, and the command line (or the sweep file's
table) overrides it key by key.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from glshade.errors import GlshadeError
from glshade.instruments.registry import instrument, method_names

#: The key that names the instrument.
METHOD_KEY = "method"


@dataclass(frozen=True)
class MeasureTable:
    """A checked ``[measure]`` table: ``method`` the instrument its settings are for (the
    one it names, else the default it was read with; None for no table), ``named``
    whether the table names it, and ``values`` its settings by key (as the file typed
    them, each checked); ``source`` the file it was read from."""

    method: str | None = None
    named: bool = False
    values: dict[str, Any] = field(default_factory=dict)
    source: str = ""

    def for_method(self, method: str) -> dict[str, Any]:
        """The values that apply to instrument ``method``: all of them when the table is
        for it, else none."""
        return dict(self.values) if self.method == method else {}

    def settings(
        self, method: str, over: dict[str, Any] | None = None, where: str = "", name: str = ""
    ) -> Any:
        """Instrument ``method``'s settings: its defaults, this table's values where they
        apply, then ``over`` (a later table's values); a bad value is one line naming
        ``where`` and the table ``name`` (default ``measure``)."""
        kind = instrument(method).settings_type
        try:
            return kind(**{**self.for_method(method), **(over or {})})
        except GlshadeError as exc:  # named as the file spells its table
            key = str(exc).removeprefix("measure.")
            raise GlshadeError(f"{where}{name or 'measure'}.{key}") from None


def file_measure_table(path: Path, default_method: str) -> MeasureTable:
    """The ``[measure]`` table of the scene file at ``path`` (an empty table where it has
    none), checked (:func:`measure_table`); ``default_method`` the instrument of its
    scene's emitter."""
    from glshade.scene.model import MEASURE_TABLE, read_toml

    data = read_toml(Path(path)).get(MEASURE_TABLE)
    return measure_table(data, f"{path}: ", default_method)


def measure_table(
    data: Any, where: str, default_method: str, name: str = "measure"
) -> MeasureTable:
    """The ``[measure]`` table ``data`` of a file (``where``: how an error names the file,
    ``"scene.toml: "``), its keys checked against the declarations of the instrument it
    names (``default_method`` when it names none); one line for anything wrong."""
    if data is None:
        return MeasureTable()
    if not isinstance(data, dict):
        raise GlshadeError(
            f"{where}[{name}] must be a table: {METHOD_KEY} ({' or '.join(method_names())}) "
            "and the instrument's settings"
        )
    values = dict(data)
    method = values.pop(METHOD_KEY, None)
    if method is not None and method not in method_names():
        raise GlshadeError(
            f"{where}{name}.{METHOD_KEY}: must be one of {', '.join(method_names())}, got "
            f"{method!r}"
        )
    chosen = method or default_method
    kind = instrument(chosen).settings_type
    names = [METHOD_KEY, *(f.name for f in fields(kind))]
    unknown = sorted(set(values) - set(names))
    if unknown:
        raise GlshadeError(
            f"{where}{name}.{unknown[0]}: unknown setting of method {chosen}; allowed: "
            f"{', '.join(names)}"
        )
    table = MeasureTable(chosen, method is not None, values, where.removesuffix(": "))
    table.settings(chosen, where=where, name=name)  # every value checked now
    return table
