"""The registry: which components exist, which one fills each slot of a scene, and the
one parameter schema they declare together.

In the spirit of Mitsuba 3's plugin registry and pygfx's render-function registry: a
component registers by its slot and name (:meth:`Registry.register`); everything else
(scene tables, validation, TOML, CLI flags, viewer controls, shader composition,
uniforms, the NumPy tracer, ``docs/scene-format.md``) asks the registry. The default
registry, :func:`registry`, is built on first use (nothing happens at import) with the
built-in components; a test or a plug-in adds its own with :meth:`Registry.registered`.
"""

from __future__ import annotations

import contextlib
import functools
import importlib
from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING

from glshade.components.base import Component, Slot
from glshade.errors import SceneError
from glshade.scene.params import Param, TableCheck

if TYPE_CHECKING:
    from glshade.scene.model import Scene

#: The scene's tables, in the order scene files list them.
TABLES: tuple[str, ...] = ("camera", "emitter", "surface", "defect", "render", "sensor")

SURFACE_KIND = Param(
    "surface.kind",
    "",
    "flat",
    "the base surface: which surface component",
    value_type="choice",
    role="feature",
    flag="--surface",
)
FRESNEL = Param(
    "render.fresnel",
    "",
    "none",
    "the Fresnel reflectance: which Fresnel component",
    value_type="choice",
    role="feature",
    flag="--fresnel",
)
REFLECTION = Param(
    "render.reflection",
    "",
    "mirror",
    "the reflection model: which reflection component",
    value_type="choice",
    role="feature",
    flag="--reflection",
)

#: The slots, in the order their GLSL is composed.
SLOTS: tuple[Slot, ...] = (
    Slot("render", "render", None, True, "precision and rays per pixel: the program's preamble"),
    Slot("camera", "camera", None, False, "pixels to rays"),
    Slot(
        "surface", "surface", SURFACE_KIND, False, "the base surface y = f(x, z) and its first hit"
    ),
    Slot(
        "defect", "defect", None, False, "the defect D(x, z) on the surface, and the hit it needs"
    ),
    Slot("emitter", "emitter", None, False, "the light source the rays land on"),
    Slot("reflection", "render", REFLECTION, False, "how the surface reflects"),
    Slot("fresnel", "render", FRESNEL, False, "how much it reflects, by the angle of incidence"),
    Slot(
        "sensor",
        "sensor",
        None,
        False,
        "what the camera's sensor makes of the radiance (noise, quantisation)",
    ),
)

#: The built-in components: module, class.
BUILTINS: tuple[tuple[str, str], ...] = (
    ("glshade.components.render", "Sampling"),
    ("glshade.components.camera_model", "CameraModel"),
    ("glshade.components.surface_flat", "Flat"),
    ("glshade.components.surface_cylinder", "Cylinder"),
    ("glshade.components.surface_sphere", "Sphere"),
    ("glshade.components.surface_formula", "Formula"),
    ("glshade.components.surface_heightmap", "HeightMap"),
    ("glshade.components.defect_gaussian", "Gaussian"),
    ("glshade.components.emitter_stripes", "Stripes"),
    ("glshade.components.reflection_mirror", "Mirror"),
    ("glshade.components.reflection_blinn_phong", "BlinnPhong"),
    ("glshade.components.reflection_microfacet", "Beckmann"),
    ("glshade.components.reflection_microfacet", "GGX"),
    ("glshade.components.fresnel", "NoFresnel"),
    ("glshade.components.fresnel", "Dielectric"),
    ("glshade.components.fresnel", "Conductor"),
    ("glshade.components.sensor", "Sensor"),
)


@dataclass(frozen=True)
class Active:
    """The components filling a scene's slots, in composition order; ``active.surface``
    is the surface component."""

    components: tuple[Component, ...]

    def __getattr__(self, slot: str) -> Component:
        for component in self.components:
            if component.slot == slot:
                return component
        raise AttributeError(f"no active component in slot {slot!r}")

    def __iter__(self) -> Iterator[Component]:
        return iter(self.components)


class Registry:
    """Components by slot and name, and the parameter schema they declare."""

    def __init__(self, slots: tuple[Slot, ...] = SLOTS, tables: tuple[str, ...] = TABLES) -> None:
        self._slots = {slot.name: slot for slot in slots}
        self._tables = tables
        self._components: dict[str, dict[str, Component]] = {slot.name: {} for slot in slots}
        self._schema: dict[
            str | None, tuple[Param, ...]
        ] = {}  # params() (key None) and per table, until the next change

    # ------------------------------------------------------------------ changes
    def register(self, component: Component) -> Component:
        """Add a component; its parameters join the schema. A parameter path that another
        component already declares must be the very same declaration."""
        slot = self._slots.get(getattr(component, "slot", None))
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
                raise ValueError(f"{param.path} is declared twice ({component!r}); share one Param")
        self._components[slot.name][component.name] = component
        self._changed()
        return component

    def _changed(self) -> None:
        self._schema = {}  # the parameter list is collected again on next use

    def unregister(self, slot: str, name: str) -> None:
        del self._components[slot][name]
        self._changed()

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
            raise SceneError(
                selector.path if selector else slot, self.allowed_names(slot), name
            ) from None

    def names(self, slot: str) -> tuple[str, ...]:
        return tuple(self._components[slot])

    def allowed_names(self, slot: str) -> str:
        return "one of " + ", ".join(self.names(slot))

    def active(self, scene: Scene) -> Active:
        """The component filling each slot of ``scene``, in composition order."""
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

    def choices(self, param: Param) -> tuple[str, ...] | None:
        """The allowed names of a selector parameter (the registered components)."""
        for slot in self._slots.values():
            if slot.selector is param:
                return self.names(slot.name)
        return None

    def checks(self, table: str) -> tuple[TableCheck, ...]:
        """Checks over several values of ``table``, from every component declaring one."""
        return tuple(
            check
            for slot in self._slots.values()
            if slot.table == table
            for component in self._components[slot.name].values()
            for check in component.checks
        )

    def owners(self, param: Param) -> tuple[Component, ...]:
        """The components declaring ``param`` (none for a slot's selector)."""
        return tuple(c for c in self.components() if any(p is param for p in c.params))


@functools.cache
def registry() -> Registry:
    """The default registry with the built-in components (built on first use)."""
    built = Registry()
    for module, name in BUILTINS:
        built.register(getattr(importlib.import_module(module), name)())
    return built
