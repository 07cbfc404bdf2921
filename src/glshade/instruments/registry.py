"""The instruments glshade knows: every ``glshade.instruments`` entry point's.

An entry point names a callable (or a list) giving :class:`~glshade.instruments.base.
Instrument` classes or instances; glshade's own (``glshade.instruments.builtin:
builtin_instruments``) gives the paper's stripe metric and phase measuring. A plug-in's
code runs under the components' guard (:mod:`glshade.components.plugin_guard`): one that
does not load, or whose declaration does not fit (:func:`declaration_problem`), is left
out whole with one warning naming it. The registry is built on first use, never at
import.
"""

from __future__ import annotations

import dataclasses
import functools
import re
import warnings
from collections.abc import Iterable
from typing import Any

from glshade.components.plugin_guard import PluginRefused, described, run_plugin_code
from glshade.components.registry import only_builtin_declared
from glshade.errors import GlshadeError, GlshadeWarning
from glshade.instruments.base import Instrument, InstrumentView, InstrumentViews
from glshade.instruments.record import Record

ENTRY_POINT_GROUP = "glshade.instruments"
BUILTIN_ENTRY_POINT = ("glshade", "glshade.instruments.builtin:builtin_instruments")
#: What an instrument's name may be: a flag's choice and a file's value.
INSTRUMENT_NAME = re.compile(r"[a-z][a-z0-9_]{0,31}")


@dataclasses.dataclass(frozen=True)
class Instruments:
    """The registered instruments by name, glshade's own first; the plug-ins refused."""

    by_name: dict[str, Instrument]
    failures: tuple[str, ...] = ()

    def names(self) -> tuple[str, ...]:
        return tuple(self.by_name)

    def get(self, name: str) -> Instrument:
        """The instrument called ``name``: an unknown name is one line listing the known."""
        found = self.by_name.get(name)
        if found is None:
            raise GlshadeError(f"method: must be one of {', '.join(self.by_name)}, got {name!r}")
        return found

    def of_settings(self, settings: Any) -> Instrument:
        """The instrument whose settings ``settings`` are."""
        for instrument in self.by_name.values():
            if type(settings) is instrument.settings_type:
                return instrument
        raise GlshadeError(
            f"settings: must be the settings of an instrument ({', '.join(self.by_name)}), got "
            f"{type(settings).__name__}"
        )


@functools.cache
def instruments() -> Instruments:
    """Every registered instrument (module doc)."""
    found: dict[str, Instrument] = {}
    failures: list[str] = []
    for entry, value, builtin in _points():
        try:
            listed = _loaded(value, builtin)
            for item in listed:
                if item.name in found:
                    raise PluginRefused(f"instrument {item.name!r} is registered already")
        except PluginRefused as exc:
            failures.append(f"instrument plug-in {entry} ({value}) left out: {exc}")
            continue
        found.update((item.name, item) for item in listed)
    for failure in failures:
        warnings.warn(failure, GlshadeWarning, stacklevel=2)
    return Instruments(found, tuple(failures))


def instrument(name: str) -> Instrument:
    """The registered instrument called ``name`` (one line listing the known otherwise)."""
    return instruments().get(name)


def instrument_for(settings: Any) -> Instrument:
    """The instrument whose settings ``settings`` are."""
    return instruments().of_settings(settings)


def method_names() -> tuple[str, ...]:
    """The registered instruments' names, glshade's own first."""
    return instruments().names()


def _points() -> list[tuple[str, str, bool]]:
    """``(entry, value, builtin)`` of every entry point of the group, glshade's first."""
    builtin = (BUILTIN_ENTRY_POINT[0], BUILTIN_ENTRY_POINT[1], True)
    if only_builtin_declared(None, ENTRY_POINT_GROUP, BUILTIN_ENTRY_POINT):
        return [builtin]
    from importlib.metadata import entry_points

    try:
        points = [(p.name, p.value, p.value == BUILTIN_ENTRY_POINT[1]) for p in entry_points(
            group=ENTRY_POINT_GROUP
        )]  # fmt: skip
    except Exception:  # an installed package's metadata that cannot be read
        points = []
    if not any(is_builtin for _, _, is_builtin in points):
        points.append(builtin)  # run from a checkout without being installed
    return sorted(points, key=lambda p: (not p[2], p[0], p[1]))


def _loaded(value: str, builtin: bool) -> list[Instrument]:
    """The instruments entry point ``value`` names, each checked; glshade's own unguarded
    (its failure is a defect)."""
    if builtin:
        return _instances(_load(value))
    loaded = run_plugin_code(functools.partial(_load, value))
    listed = run_plugin_code(functools.partial(_instances, loaded))
    for item in listed:
        problem = run_plugin_code(functools.partial(declaration_problem, item))
        if problem is not None:
            raise PluginRefused(f"does not fit: {problem}")
    return listed


def _load(value: str) -> Any:
    import importlib

    module_name, _, attribute = value.partition(":")
    loaded: Any = importlib.import_module(module_name.strip())
    for part in attribute.strip().split(".") if attribute.strip() else ():
        loaded = getattr(loaded, part)
    return loaded() if callable(loaded) and not isinstance(loaded, type) else loaded


def _instances(loaded: Any) -> list[Instrument]:
    items: Iterable[Any] = loaded if isinstance(loaded, (list, tuple)) else (loaded,)
    out = []
    for item in items:
        made = item() if isinstance(item, type) else item
        if not isinstance(made, Instrument):
            raise PluginRefused(f"does not fit: {type(made).__name__} is not an Instrument")
        out.append(made)
    return out


def declaration_problem(item: Instrument) -> str | None:
    """What is malformed in an instrument's declaration, in one line; None when nothing."""
    name = getattr(item, "name", None)
    if not isinstance(name, str) or not INSTRUMENT_NAME.fullmatch(name):
        return f"instrument name {name!r}: must match {INSTRUMENT_NAME.pattern}"
    settings = getattr(item, "settings_type", None)
    if not (isinstance(settings, type) and dataclasses.is_dataclass(settings)):
        return f"instrument {name!r}: settings_type must be a dataclass"
    record = getattr(item, "record_type", None)
    if not (isinstance(record, type) and issubclass(record, Record)):
        return f"instrument {name!r}: record_type must be a Record"
    try:
        settings()
    except Exception as exc:
        return f"instrument {name!r}: its default settings fail: {described(exc)}"
    columns = {c.name for c in record.columns()}
    missing = [o for o in getattr(item, "outputs", ()) if o not in columns]
    missing += [name for name in ("status", "status_reason") if name not in columns]
    if missing:
        return f"instrument {name!r}: {missing} are not columns of its record"
    for goal in getattr(item, "goals", ()):
        if goal.column not in columns or goal.method != name:
            return f"instrument {name!r}: goal {goal.name!r} reads no column of its record"
    return _views_problem(item)


def _views_problem(item: Instrument) -> str | None:
    """What is malformed in what an instrument offers the viewer; None when nothing."""
    offer = item.views()
    if offer is None:
        return None
    if not isinstance(offer, InstrumentViews) or not offer.views:
        return f"instrument {item.name!r}: views() must give InstrumentViews with views"
    names = [getattr(view, "name", None) for view in offer.views]
    if not all(isinstance(view, InstrumentView) for view in offer.views):
        return f"instrument {item.name!r}: each of its views must be an InstrumentView"
    if len(set(names)) != len(names):
        return f"instrument {item.name!r}: its views' names repeat ({', '.join(map(str, names))})"
    if not (isinstance(offer.size, int) and 16 <= offer.size <= 16384):
        return f"instrument {item.name!r}: its views' case size must be in [16, 16384]"
    return None
