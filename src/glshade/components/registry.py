"""The registry: which components exist, which one fills each slot of a scene, and the
one parameter schema they declare together.

In the spirit of Mitsuba 3's plugin registry and pytest's plug-ins: every component,
built-in or installed, is found through one entry-point group, ``glshade.components``
(an entry point names a component class, or a module whose ``COMPONENTS`` lists
several); :meth:`Registry.register` adds one by hand (a test's toy). Everything else
(scene tables, validation, TOML, CLI flags, viewer controls, shader composition,
uniforms, the NumPy tracer, ``docs/scene-format.md``) asks the registry. The default
registry, :func:`registry`, is built on first use (nothing happens at import); a broken
plug-in names itself in the error.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import importlib
import os
import pkgutil
import re
import sys
from collections.abc import Iterable, Iterator
from importlib.machinery import PathFinder
from types import ModuleType
from typing import Any

from glshade.components.base import Active, Component, SceneView, Slot
from glshade.components.emitter.table import EmitterTable
from glshade.components.fresnel.table import FresnelChoice
from glshade.components.reflection.table import ReflectionChoice
from glshade.components.surface.table import SurfaceTable
from glshade.errors import GlshadeError, SceneError
from glshade.params import Param, Table, TableCheck

#: The entry-point group of components (built-in and third-party).
ENTRY_POINT_GROUP = "glshade.components"
#: The scene's tables, in the order scene files list them.
TABLES: tuple[str, ...] = ("camera", "emitter", "surface", "defect", "render", "sensor")

#: The slots, in the order their GLSL is composed.
SLOTS: tuple[Slot, ...] = (
    Slot("render", "render", None, True, "precision and rays per pixel: the program's preamble",
         "render.glsl"),
    Slot("camera", "camera", None, False, "pixels to rays", "camera.glsl"),
    Slot("surface", "surface", SurfaceTable.declaration("kind"), False,
         "the base surface y = f(x, z) and its first hit", "surface.glsl"),
    Slot("defect", "defect", None, False,
         "the defect D(x, z) on the surface, and the hit it needs", "defect.glsl"),
    Slot("emitter", "emitter", EmitterTable.declaration("kind"), False,
         "the light source the rays land on", "emitter.glsl"),
    Slot("reflection", "render", ReflectionChoice.declaration("reflection"), False,
         "how the surface reflects", "reflection.glsl"),
    Slot("fresnel", "render", FresnelChoice.declaration("fresnel"), False,
         "how much it reflects, by the angle of incidence", "fresnel.glsl"),
    Slot("sensor", "sensor", None, False,
         "what the camera's sensor makes of the radiance (noise, quantisation)"),
)  # fmt: skip


class Registry:
    """Components by slot and name, and the parameter schema they declare."""

    def __init__(self, slots: tuple[Slot, ...] = SLOTS, tables: tuple[str, ...] = TABLES) -> None:
        self._slots = {slot.name: slot for slot in slots}
        self._tables = tables
        self._components: dict[str, dict[str, Component]] = {slot.name: {} for slot in slots}
        #: params() (key None) and per table, until the next change
        self._schema: dict[str | None, tuple[Param, ...]] = {}

    # ------------------------------------------------------------------ changes
    def register(self, component: Component) -> Component:
        """Add a component; its parameters join the schema. A parameter path that another
        component already declares must be the very same declaration (a shared table)."""
        slot = self._slots.get(getattr(component, "slot", ""))
        if slot is None:
            raise ValueError(f"{component!r}: unknown slot; slots are {', '.join(self._slots)}")
        if component.name in self._components[slot.name]:
            raise ValueError(f"{slot.name} component {component.name!r} is already registered")
        if slot.selector is None and self._components[slot.name]:
            raise ValueError(f"slot {slot.name!r} has no selector: it takes one component")
        known = {param.path: param for param in self.params()}
        for param in component.params:
            if param.table != slot.table:
                raise ValueError(
                    f"{component!r} declares {param.path} outside its table {slot.table!r}"
                )
            if param.path in known and known[param.path] is not param:
                raise ValueError(
                    f"{param.path} is declared twice ({component!r}); share one declaration"
                )
        self._components[slot.name][component.name] = component
        self._schema = {}
        return component

    def unregister(self, slot: str, name: str) -> None:
        del self._components[slot][name]
        self._schema = {}

    @contextlib.contextmanager
    def registered(self, component: Component) -> Iterator[Component]:
        """Register ``component`` for the duration of a ``with`` block."""
        self.register(component)
        try:
            yield component
        finally:
            self.unregister(component.slot, component.name)

    # ------------------------------------------------------------------ lookup
    def slots(self) -> tuple[Slot, ...]:
        return tuple(self._slots.values())

    def slot(self, name: str) -> Slot:
        return self._slots[name]

    def tables(self) -> tuple[str, ...]:
        return self._tables

    def components(self, slot: str | None = None) -> tuple[Component, ...]:
        names = [slot] if slot is not None else list(self._slots)
        return tuple(c for name in names for c in self._components[name].values())

    def get(self, slot: str, name: str) -> Component:
        try:
            return self._components[slot][name]
        except KeyError:
            selector = self._slots[slot].selector
            field = selector.path if selector else slot
            raise SceneError(field, self.allowed_names(slot), name) from None

    def names(self, slot: str) -> tuple[str, ...]:
        return tuple(self._components[slot])

    def allowed_names(self, slot: str) -> str:
        return "one of " + ", ".join(self.names(slot))

    def active(self, scene: SceneView) -> Active:
        """The component filling each slot of ``scene``, in composition order (a scene
        asks once: ``scene.active``)."""
        chosen = []
        for slot in self._slots.values():
            if slot.selector is None:
                chosen.append(next(iter(self._components[slot.name].values())))
            else:
                value = getattr(getattr(scene, slot.selector.table), slot.selector.key)
                chosen.append(self.get(slot.name, value))
        return Active(tuple(chosen))

    # ------------------------------------------------------------------ schema
    def params(self) -> tuple[Param, ...]:
        """Every parameter, once: by table in file order, within a table by slot in
        composition order, each slot's selector before its components' parameters."""
        if None not in self._schema:
            self._schema[None] = self._collect_params()
        return self._schema[None]

    def _collect_params(self) -> tuple[Param, ...]:
        seen: dict[str, Param] = {}
        for table in self._tables:
            for slot in self._slots.values():
                if slot.table != table:
                    continue
                if slot.selector is not None:
                    seen.setdefault(slot.selector.path, slot.selector)
                for component in self._components[slot.name].values():
                    for param in component.params:
                        seen.setdefault(param.path, param)
        return tuple(seen.values())

    def table_params(self, table: str) -> tuple[Param, ...]:
        if table not in self._schema:
            self._schema[table] = tuple(p for p in self.params() if p.table == table)
        return self._schema[table]

    def param(self, path: str) -> Param:
        """The declaration of ``table.key``; a SceneError naming the known ones if none."""
        for param in self.params():
            if param.path == path:
                return param
        table = path.partition(".")[0]
        if table not in self._tables:
            raise SceneError(
                table, "one of the tables " + ", ".join(self._tables) + " (unknown table)"
            )
        keys = ", ".join(p.key for p in self.table_params(table))
        raise SceneError(path, f"one of the keys {keys} (unknown key)")

    def entry(self, path: str) -> tuple[Param, str] | None:
        """A named entry of a parameter that holds a table of named numbers
        (``surface.parameters.a``: a formula's parameter ``a``) -> that parameter's
        declaration and the entry's name; None for a ``table.key`` path. A SceneError
        names a longer path whose ``table.key`` holds no such table."""
        if path.count(".") < 2:
            return None
        table, key, name = path.split(".", 2)
        param = self.param(f"{table}.{key}")
        if param.value_type != "table":
            raise SceneError(
                path,
                "a dotted path table.key (camera.theta_deg), or table.key.name for an entry "
                f"of a table of named numbers (surface.parameters.a); {param.path} is not a "
                "table",
            )
        if not name.isidentifier():
            raise SceneError(path, f"{param.path}.NAME with NAME a name such as a or b2")
        return param, name

    def choices(self, param: Param) -> tuple[str, ...] | None:
        """The allowed names of a selector parameter (the registered components)."""
        for slot in self._slots.values():
            if slot.selector is param:
                return self.names(slot.name)
        return None

    def checks(self, table: str) -> tuple[TableCheck, ...]:
        """Checks over several values of ``table``, from every component declaring one."""
        found: dict[TableCheck, None] = {}
        for component in self.table_components(table):
            if component.table is not None:
                found.update(dict.fromkeys(component.table.checks()))
        return tuple(found)

    def owners(self, param: Param) -> tuple[Component, ...]:
        """The components declaring ``param`` (none for a slot's selector)."""
        return tuple(c for c in self.components() if any(p is param for p in c.params))

    def table_components(self, table: str) -> tuple[Component, ...]:
        """Every registered component whose parameters live in ``table``."""
        return tuple(
            c
            for slot in self._slots.values()
            if slot.table == table
            for c in self.components(slot.name)
        )

    def table_class(self, base: type[Table]) -> type[Table]:
        """``base`` (a scene's table class: its own fields) joined with the tables of
        every registered component of its table: a frozen dataclass whose fields are all
        their declarations, whose selectors accept the registered names. One class per
        set of parts, so tables made before and after a plug-in came and went compare
        equal."""
        parts = [c.table for c in self.table_components(base.table) if c.table is not None]
        choices = tuple(
            (slot.selector.key, self.names(slot.name))
            for slot in self._slots.values()
            if slot.table == base.table and slot.selector is not None
        )
        return _joined(base, _most_derived(parts), choices)  # type: ignore[arg-type]


def _most_derived(classes: Iterable[type]) -> tuple[type, ...]:
    """``classes`` without repeats and without any that another one derives from (a
    valid list of bases)."""
    unique = list(dict.fromkeys(classes))
    return tuple(c for c in unique if not any(o is not c and issubclass(o, c) for o in unique))


@functools.lru_cache(maxsize=64)
def _joined(
    base: type[Table], parts: tuple[type, ...], choices: tuple[tuple[str, tuple[str, ...]], ...]
) -> type[Table]:
    parts = tuple(p for p in parts if not issubclass(base, p))
    joined = dataclasses.make_dataclass(
        base.__name__,
        [],
        bases=(*reversed(parts), base),
        frozen=True,
        namespace={"selector_choices": dict(choices)},
    )
    joined.__module__ = base.__module__
    joined.__qualname__ = base.__qualname__
    joined.__doc__ = base.__doc__
    return joined


# --------------------------------------------------------------------------- discovery
#: glshade's own entry point of the group (``pyproject.toml``).
BUILTIN_ENTRY_POINT = ("glshade", "glshade.components.registry:builtin_components")


def discovered() -> list[Component]:
    """One instance of every component the ``glshade.components`` entry points name:
    glshade's own first, then each plug-in's; by slot, and within a slot by ``rank``
    (then name). A plug-in that does not load names itself."""
    found: list[Component] = []
    if only_builtin_declared():  # what importlib.metadata would find, without its ~20 ms
        found.extend(_instances(builtin_components, BUILTIN_ENTRY_POINT[0]))
    else:
        points = _entry_points()
        if not any(point.value == BUILTIN_ENTRY_POINT[1] for point in points):
            # glshade run from a checkout (PYTHONPATH=src) without being installed: no
            # distribution declares its own components, which are there all the same
            found.extend(_instances(builtin_components, BUILTIN_ENTRY_POINT[0]))
        for point in points:
            try:
                loaded = point.load()
                found.extend(_instances(loaded, point.name))
            except GlshadeError:
                raise
            except Exception as exc:  # a broken plug-in: say which
                raise GlshadeError(
                    f"glshade plug-in {point.name!r} ({point.value}) does not load: "
                    f"{type(exc).__name__}: {exc}"
                ) from None
    order = {slot.name: index for index, slot in enumerate(SLOTS)}
    return sorted(found, key=lambda c: (order.get(getattr(c, "slot", ""), len(order)), c.rank))


def _entry_points() -> list[Any]:
    """The group's entry points (``importlib.metadata``), glshade's first, then by
    distribution name and entry name."""
    from importlib.metadata import entry_points

    points = list(entry_points(group=ENTRY_POINT_GROUP))
    if len(points) > 1:  # a distribution's name reads its metadata: only when there are plug-ins
        points.sort(key=_entry_order)
    return points


def only_builtin_declared(path: list[str] | None = None) -> bool:
    """True when ``importlib.metadata.entry_points(group=ENTRY_POINT_GROUP)`` would return
    glshade's own entry point and nothing else, read from the distributions'
    ``entry_points.txt`` in the folders of ``path`` (default ``sys.path``) the way
    ``importlib.metadata`` finds them: the first ``glshade`` distribution counts, and
    any other distribution that declares the group is a plug-in. False whenever the
    plain folder scan cannot be sure: a plug-in, a zip file or an egg on the path, a
    finder of distributions besides Python's own."""
    if any(
        getattr(finder, "find_distributions", None) is not None and not _reads_sys_path(finder)
        for finder in sys.meta_path
    ):
        return False
    glshade_seen, builtin = False, False
    for entry in sys.path if path is None else path:
        folder = entry or "."
        if os.path.basename(folder).lower().endswith(".egg"):
            return False
        try:
            children = os.listdir(folder)
        except NotADirectoryError:
            return False  # a zip file: importlib.metadata reads inside it
        except OSError:
            continue
        for child in children:
            low = child.lower()
            if not low.endswith((".dist-info", ".egg-info")):
                continue
            declared = _declared(os.path.join(folder, child))
            name = re.sub(r"[-_.]+", "_", low.rpartition(".")[0].partition("-")[0])
            if name != "glshade":
                if declared:
                    return False
            elif not glshade_seen:
                glshade_seen, builtin = True, declared == [BUILTIN_ENTRY_POINT]
    return builtin


def _reads_sys_path(finder: Any) -> bool:
    """Whether ``finder`` finds distributions exactly as Python's own does, in the folders
    of ``sys.path``: Python's ``PathFinder``, or the ``importlib_metadata`` back-port's
    ``MetadataPathFinder``, which Dask imports and which takes over from it."""
    kind = type(finder)
    return finder is PathFinder or (
        kind.__name__ == "MetadataPathFinder" and kind.__module__.startswith("importlib_metadata")
    )


def _declared(info: str) -> list[tuple[str, str]]:
    """The ``(name, value)`` pairs of the group in a distribution's ``entry_points.txt``
    (none when it has none), parsed as ``importlib.metadata`` parses it."""
    try:
        with open(os.path.join(info, "entry_points.txt"), encoding="utf-8") as file:
            text = file.read()
    except (OSError, UnicodeDecodeError):
        return []
    pairs, section = [], None
    for line in map(str.strip, text.splitlines()):
        if not line or line.startswith("#"):
            continue
        if line.startswith("[") and line.endswith("]"):
            section = line.strip("[]")
        elif section == ENTRY_POINT_GROUP:
            name, _, value = line.partition("=")
            pairs.append((name.strip(), value.strip()))
    return pairs


def _entry_order(point: Any) -> tuple[bool, str, str]:
    distribution = getattr(getattr(point, "dist", None), "name", "") or ""
    return distribution != "glshade", distribution, point.name


def _instances(loaded: Any, name: str) -> list[Component]:
    """The components an entry point names: a component class, a module's
    ``COMPONENTS``, or a function returning components."""
    if isinstance(loaded, ModuleType):
        loaded = getattr(loaded, "COMPONENTS", ())
    elif callable(loaded) and not isinstance(loaded, type):
        loaded = loaded()
    items = loaded if isinstance(loaded, (list, tuple)) else (loaded,)
    out = []
    for item in items:
        if isinstance(item, type) and issubclass(item, Component):
            item = item()
        if not isinstance(item, Component):
            raise GlshadeError(f"glshade plug-in {name!r} names {item!r}, not a component")
        out.append(item)
    return out


def builtin_components() -> list[Component]:
    """glshade's own components (its entry point): every folder
    ``glshade/components/<slot>/<name>/`` lists its classes in ``COMPONENTS``, so a new
    built-in component is a new folder and nothing else."""
    found: list[Component] = []
    for slot in SLOTS:
        package = importlib.import_module(f"{__package__}.{slot.name}")
        for info in sorted(pkgutil.iter_modules(package.__path__), key=lambda m: m.name):
            if info.ispkg:
                module = importlib.import_module(f"{package.__name__}.{info.name}")
                found.extend(_instances(module, info.name))
    return found


@functools.cache
def registry() -> Registry:
    """The default registry with every component the entry points name (built on first
    use)."""
    built = Registry()
    for component in discovered():
        try:
            built.register(component)
        except ValueError as exc:
            raise GlshadeError(f"glshade plug-in {component!r} does not fit: {exc}") from None
    return built
