"""The registry: which components exist, which one fills each slot of a scene, and the
one parameter schema they declare together.

In the spirit of Mitsuba 3's plugin registry and pytest's plug-ins: every component,
built-in or installed, is found through one entry-point group, ``glshade.components``
(an entry point names a component class, or a module whose ``COMPONENTS`` lists
several); :meth:`Registry.register` adds one by hand (a test's toy). Everything else
(scene tables, validation, TOML, CLI flags, viewer controls, shader composition,
uniforms, the NumPy tracer, ``docs/scene-format.md``) asks the registry. The default
registry, :func:`registry`, is built on first use (nothing happens at import).

A broken plug-in never takes glshade down: its import and everything glshade reads of
its components run under a guard (:mod:`glshade.components.plugin_guard`), and what
every component declares is checked (:func:`declaration_problem`). A plug-in that fails
either way is left out whole, with one warning that names it (its entry point and
module) and what went wrong (:class:`PluginFailure`, :attr:`Registry.failures`); the
rest of glshade works, and a scene that asks for one of its components is refused as
naming an unknown one. glshade's own components are not guarded: their failure is a
defect of glshade.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import importlib
import math
import os
import pkgutil
import re
import sys
import warnings
from collections.abc import Iterable, Iterator, Mapping
from importlib.machinery import PathFinder
from types import ModuleType
from typing import Any

from glshade.components.base import Active, Component, SceneView, Slot
from glshade.components.emitter.table import EmitterTable
from glshade.components.fresnel.table import FresnelChoice
from glshade.components.plugin_guard import PluginRefused, described, run_plugin_code
from glshade.components.reflection.table import ReflectionChoice
from glshade.components.surface.table import SurfaceTable
from glshade.errors import GlshadeError, GlshadeWarning, SceneError, printable, shown_value
from glshade.params import Param, Table, TableCheck

#: The entry-point group of components (built-in and third-party).
ENTRY_POINT_GROUP = "glshade.components"
#: The scene's tables, in the order scene files list them.
TABLES: tuple[str, ...] = ("camera", "emitter", "surface", "defect", "render", "sensor", "part")

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
    Slot("part", "part", None, False, "where the part (its surface and dent) stands in the world"),
)  # fmt: skip


class Registry:
    """Components by slot and name, and the parameter schema they declare."""

    def __init__(self, slots: tuple[Slot, ...] = SLOTS, tables: tuple[str, ...] = TABLES) -> None:
        self._slots = {slot.name: slot for slot in slots}
        self._tables = tables
        self._components: dict[str, dict[str, Component]] = {slot.name: {} for slot in slots}
        #: params() (key None) and per table, until the next change
        self._schema: dict[str | None, tuple[Param, ...]] = {}
        #: The plug-ins left out when the registry was built (:func:`registry`).
        self.failures: tuple[PluginFailure, ...] = ()

    # ------------------------------------------------------------------ changes
    def register(self, component: Component) -> Component:
        """Add a component; its parameters join the schema. A parameter path that another
        component already declares must be the very same declaration (a shared table). A
        malformed declaration (:func:`declaration_problem`) raises ValueError too."""
        problem = declaration_problem(component, self._slots)
        if problem is not None:
            raise ValueError(problem)
        slot = self._slots[component.slot]
        called = f"{slot.name} component {component.name!r}"
        if component.name in self._components[slot.name]:
            raise ValueError(f"{called} is already registered")
        if slot.selector is None and self._components[slot.name]:
            raise ValueError(f"slot {slot.name!r} has no selector: it takes one component")
        known = {param.path: param for param in self.params()}
        for param in component.params:
            if param.table != slot.table:
                raise ValueError(f"{called} declares {param.path} outside its table {slot.table!r}")
            if param.path in known and known[param.path] is not param:
                raise ValueError(
                    f"{param.path} is declared twice ({called}); share one declaration"
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
        """The declaration of ``table.key``; a SceneError naming the known ones if none.
        ``table.key[i]``, a component of a vector parameter (``camera.position[1]``), is
        declared as one number in the vector's unit."""
        if path.endswith("]") and "[" in path:
            return self.component(path)
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

    def component(self, path: str) -> Param:
        """The declaration of component ``i`` of the vector ``table.key[i]``."""
        whole, _, rest = path.partition("[")
        vector = self.param(whole)
        index = rest[:-1]
        size = vector.size if vector.value_type == "vector" else 0
        if not size or not index.isdigit() or int(index) >= size:
            allowed = f"{whole}[0] to {whole}[{size - 1}]" if size else "a vector's component"
            raise SceneError(path, allowed)
        default = None if vector.default is None else vector.default[int(index)]
        return dataclasses.replace(
            vector, path=path, value_type="real", default=default, size=0, flag=None,
            control=None, allowed_text=None, role="uniform",
        )  # fmt: skip

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


@dataclasses.dataclass(frozen=True)
class Plugin:
    """The components one entry point named: its name and value (``module:attribute``)."""

    entry: str
    value: str
    components: tuple[Component, ...]


@dataclasses.dataclass(frozen=True)
class PluginFailure:
    """A plug-in glshade runs without: its entry point's name and value (``module`` or
    ``module:attribute``) and what went wrong (one line: ``does not load: ...``)."""

    entry: str
    value: str
    problem: str

    def line(self) -> str:
        return printable(
            f"plug-in {self.entry!r} ({self.value}) {self.problem}; glshade runs without it"
        )


def discovered() -> list[Component]:
    """One instance of every component the ``glshade.components`` entry points name:
    glshade's own first, then each plug-in's that loads; by slot, and within a slot by
    ``rank`` (then name)."""
    plugins, _ = discover()
    return _ordered(c for plugin in plugins for c in plugin.components)


def _register(built: Registry, component: Component) -> None:
    """A plug-in's ``component`` registered in ``built``; PluginRefused naming why not."""
    try:
        built.register(component)
    except ValueError as exc:
        raise PluginRefused(str(exc)) from None


def _ordered(components: Iterable[Component]) -> list[Component]:
    order = {slot.name: index for index, slot in enumerate(SLOTS)}
    return sorted(components, key=lambda c: (order.get(c.slot, len(order)), c.rank))


def discover() -> tuple[list[Plugin], list[PluginFailure]]:
    """The components of every ``glshade.components`` entry point, glshade's own first,
    each plug-in loaded under the guard and its declarations checked; the plug-ins that
    failed, each named with what went wrong."""
    if only_builtin_declared():  # what importlib.metadata would find, without its ~20 ms
        return [_builtin_plugin(*BUILTIN_ENTRY_POINT, builtin_components)], []
    plugins: list[Plugin] = []
    failures: list[PluginFailure] = []
    try:
        points = _entry_points()
    except Exception as exc:  # an installed package's metadata that cannot be read
        points = []
        failures.append(PluginFailure("*", ENTRY_POINT_GROUP, f"cannot be listed: {exc}"))
    if not any(point.value == BUILTIN_ENTRY_POINT[1] for point in points):
        # glshade run from a checkout (PYTHONPATH=src) without being installed: no
        # distribution declares its own components, which are there all the same
        plugins.append(_builtin_plugin(*BUILTIN_ENTRY_POINT, builtin_components))
    for point in points:
        if point.value == BUILTIN_ENTRY_POINT[1]:  # glshade's own: its failure is a defect
            plugins.append(_builtin_plugin(point.name, point.value, point.load()))
            continue
        try:
            components = run_plugin_code(functools.partial(_checked, point))
        except PluginRefused as exc:
            failures.append(PluginFailure(point.name, point.value, str(exc)))
        else:
            plugins.append(Plugin(point.name, point.value, components))
    return plugins, failures


def _builtin_plugin(entry: str, value: str, loaded: Any) -> Plugin:
    return Plugin(entry, value, tuple(_instances(loaded, entry)))


def _checked(point: Any) -> tuple[Component, ...]:
    """The components entry point ``point`` names (the plug-in imported), each one's
    declaration checked (run under the guard: all of it is the plug-in's code)."""
    try:
        loaded = point.load()
    except BaseException as exc:
        raise PluginRefused(f"does not load: {described(exc)}") from None
    try:
        components = tuple(_instances(loaded, point.name))
    except GlshadeError as exc:
        raise PluginRefused(f"does not fit: {exc}") from None
    except BaseException as exc:
        raise PluginRefused(f"does not fit: {described(exc)}") from None
    for component in components:
        try:
            problem = declaration_problem(component)
        except BaseException as exc:  # reading a declaration raised
            problem = f"{_called(component)}: {described(exc)}"
        if problem is not None:
            raise PluginRefused(f"does not fit: {problem}")
    return components


def _called(component: Component) -> str:
    """``surface component 'x'`` where its slot and name can be read, else its class."""
    try:
        slot, name = component.slot, component.name
        if isinstance(slot, str) and isinstance(name, str):
            return f"{slot} component {name!r}"
    except BaseException:  # the guard around the caller handles a real Ctrl-C
        pass
    return f"component {type(component).__qualname__}"


def _entry_points() -> list[Any]:
    """The group's entry points (``importlib.metadata``), glshade's first, then by
    distribution name and entry name."""
    from importlib.metadata import entry_points

    points = list(entry_points(group=ENTRY_POINT_GROUP))
    if len(points) > 1:  # a distribution's name reads its metadata: only when there are plug-ins
        points.sort(key=_entry_order)
    return points


def only_builtin_declared(
    path: list[str] | None = None,
    group: str = ENTRY_POINT_GROUP,
    builtin_point: tuple[str, str] = BUILTIN_ENTRY_POINT,
) -> bool:
    """True when ``importlib.metadata.entry_points(group=group)`` would return
    glshade's own entry point (``builtin_point``) and nothing else, read from the distributions'
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
            declared = _declared(os.path.join(folder, child), group)
            name = re.sub(r"[-_.]+", "_", low.rpartition(".")[0].partition("-")[0])
            if name != "glshade":
                if declared:
                    return False
            elif not glshade_seen:
                glshade_seen, builtin = True, declared == [builtin_point]
    return builtin


def _reads_sys_path(finder: Any) -> bool:
    """Whether ``finder`` finds distributions exactly as Python's own does, in the folders
    of ``sys.path``: Python's ``PathFinder``, or the ``importlib_metadata`` back-port's
    ``MetadataPathFinder``, which Dask imports and which takes over from it."""
    kind = type(finder)
    return finder is PathFinder or (
        kind.__name__ == "MetadataPathFinder" and kind.__module__.startswith("importlib_metadata")
    )


def _declared(info: str, group: str = ENTRY_POINT_GROUP) -> list[tuple[str, str]]:
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
        elif section == group:
            name, _, value = line.partition("=")
            pairs.append((name.strip(), value.strip()))
    return pairs


def _entry_order(point: Any) -> tuple[bool, str, str]:
    distribution = getattr(getattr(point, "dist", None), "name", "") or ""
    return distribution != "glshade", distribution, point.name


#: What a component's name may be: it is a scene file's value, a flag's choice and a
#: folder of the GLSL namespaces (``surface.flat``).
COMPONENT_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_-]{0,63}")


def declaration_problem(component: Any, slots: Mapping[str, Slot] | None = None) -> str | None:
    """What is malformed in ``component``'s declaration, in one line naming it; None when
    nothing is. Its slot must be one of ``slots`` (default: glshade's), its name a
    :data:`COMPONENT_NAME`, its rank a finite number, its doc a string, its table None or
    a :class:`~glshade.params.Table` dataclass of its slot's table, its params a tuple of
    :class:`~glshade.params.Param` with distinct paths, its shorthands (Param, field
    name) pairs. Reading them may run a plug-in's code: call it under the guard."""
    slots = {slot.name: slot for slot in SLOTS} if slots is None else slots
    if not isinstance(component, Component):
        return f"{shown_value(component)} is not a component"
    slot = component.slot
    if not isinstance(slot, str) or slot not in slots:
        return f"its slot must be one of {', '.join(slots)}, got {shown_value(slot)}"
    name = component.name
    if not isinstance(name, str) or not COMPONENT_NAME.fullmatch(name):
        return (
            f"a {slot} component's name must be a letter, then letters, digits, '_' or '-' "
            f"(at most 64), got {shown_value(name)}"
        )
    problem = _fields_problem(component, slots[slot])
    return None if problem is None else f"{slot} component {name!r}: {problem}"


def _fields_problem(component: Component, slot: Slot) -> str | None:
    """What is malformed in the declaration of ``component`` besides its slot and name."""
    rank, table, params = component.rank, component.table, component.params
    if isinstance(rank, bool) or not isinstance(rank, (int, float)) or not math.isfinite(rank):
        return f"its rank must be a finite number, got {shown_value(rank)}"
    if not isinstance(component.doc, str):
        return f"its doc must be a string, got {shown_value(component.doc)}"
    if table is not None and not (
        isinstance(table, type)
        and issubclass(table, Table)
        and dataclasses.is_dataclass(table)
        and getattr(table, "table", None) == slot.table
    ):
        return (
            f"its table must be None or a glshade.params.Table dataclass of the {slot.table!r} "
            f"table, got {shown_value(table)}"
        )
    if not isinstance(params, tuple) or not all(isinstance(p, Param) for p in params):
        return f"its params must be a tuple of glshade.params.Param, got {shown_value(params)}"
    paths = [p.path for p in params]
    if len(set(paths)) != len(paths):
        twice = sorted({path for path in paths if paths.count(path) > 1})
        return f"its params declare {', '.join(twice)} twice"
    shorthands = component.shorthands
    if not isinstance(shorthands, tuple) or not all(
        isinstance(pair, tuple)
        and len(pair) == 2
        and isinstance(pair[0], Param)
        and isinstance(pair[1], str)
        for pair in shorthands
    ):
        return f"its shorthands must be (Param, field name) pairs, got {shown_value(shorthands)}"
    return None


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
            raise GlshadeError(f"entry point {name!r} names {shown_value(item)}, not a component")
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
    use); a plug-in that does not load or fit is left out whole, with one warning
    naming it (:attr:`Registry.failures`)."""
    built = Registry()
    plugins, failures = discover()
    owner = {id(c): index for index, plugin in enumerate(plugins) for c in plugin.components}
    refused: dict[int, str] = {}
    for component in _ordered(c for plugin in plugins for c in plugin.components):
        index = owner[id(component)]
        if index in refused:
            continue
        if plugins[index].value == BUILTIN_ENTRY_POINT[1]:
            built.register(component)  # glshade's own: a failure is a defect
            continue
        try:
            run_plugin_code(functools.partial(_register, built, component))
        except PluginRefused as exc:
            refused[index] = f"does not fit: {exc}"
    for index, problem in refused.items():
        plugin = plugins[index]
        for component in plugin.components:
            if built._components[component.slot].get(component.name) is component:
                built.unregister(component.slot, component.name)
        failures.append(PluginFailure(plugin.entry, plugin.value, problem))
    built.failures = tuple(failures)
    for failure in failures:
        warnings.warn(failure.line(), GlshadeWarning, stacklevel=2)
    return built
