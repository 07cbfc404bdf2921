"""The scene: what the camera sees, as six tables of the parameters its components declare.

Conventions: the world frame has the gazing point at the origin, ``+y`` up, the plane of
incidence ``yz``, the camera on ``+z`` and the emitter on ``-z``; every length is in
millimetres, every angle that crosses the user boundary in degrees.

Each table is a frozen dataclass declared by the component that owns it (the camera's,
the defect's, the sensor's) or, for the surface, emitter and render tables that several
components share, the slot's own fields joined with those of every registered
component (:meth:`glshade.components.registry.Registry.table_class`): ``Surface(kind=
"sphere", radius=70)`` is such a table. A table validates itself on construction: a value
out of range raises :class:`~glshade.errors.SceneError` naming the field as a scene file
spells it (``camera.theta_deg``) and the allowed range. ``Scene.from_dict`` /
``Scene.to_dict`` map to and from the TOML layout of ``docs/scene-format.md`` and
round-trip. A scene resolves once which component fills each slot (:attr:`Scene.active`).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, fields, replace
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from glshade.components.base import Active
from glshade.components.camera.perspective.table import Camera
from glshade.components.defect.gaussian.table import Defect
from glshade.components.emitter.stripes.table import Emitter as StripesTable
from glshade.components.emitter.table import EmitterTable
from glshade.components.image_scale import auto_period_mm
from glshade.components.part.rigid.table import Part
from glshade.components.registry import registry
from glshade.components.render.table import RenderTable
from glshade.components.sensor.linear.table import Sensor
from glshade.components.surface.table import SurfaceTable
from glshade.errors import GlshadeError, SceneError
from glshade.params import Table
from glshade.rig import CameraPose, EmitterPlane, Gaze
from glshade.scene.station import Station, gaze_of, is_rig, station_of

#: The tables a scene file always lists (a table that switches something on by its
#: presence, ``[sensor]``, is written only when on).
ALWAYS_WRITTEN: tuple[str, ...] = ("camera", "emitter", "surface", "defect", "render")


# --------------------------------------------------------------------------- tables
class _Joined:
    """Mixin of the tables several components share: ``Surface(...)`` builds the class
    joined from the registered components' tables (validated), and pickles by name."""

    def __new__(cls, *args: Any, **kwargs: Any) -> Any:
        joined: type = registry().table_class(cls) if cls in _SHARED else cls  # type: ignore[arg-type]
        return object.__new__(joined)

    def __reduce__(self) -> tuple[Any, ...]:
        return _rebuild_table, (self.table, self.values())  # type: ignore[attr-defined]


@dataclass(frozen=True)
class Surface(_Joined, SurfaceTable):
    """The base surface ``y = f(x, z)``: ``kind`` names the surface component; its
    parameters (``radius``, ``axis``, ``expression``, ``file``, ...) are those the
    registered kinds declare."""

    @property
    def concave(self) -> bool:
        """Curved upwards somewhere at the gaze point (a bowl, a trough)."""
        alone = Scene(surface=self)
        return any(f2 > 0.0 for f2 in alone.active.surface.second_derivatives(alone))


@dataclass(frozen=True)
class RenderSettings(_Joined, RenderTable):
    """How a frame is computed: ``precision``, ``supersample``, ``reflection`` and
    ``fresnel`` (which components) and the parameters those declare."""


@dataclass(frozen=True)
class Emitter(_Joined, EmitterTable, StripesTable):
    """The light source: ``kind`` names the emitter component (default the stripes,
    whose parameters are typed here); the other kinds' parameters (the fringes'
    ``periods``, ``shifts``, ...) are those the registered emitters declare."""


_SHARED: tuple[type, ...] = (Surface, RenderSettings, Emitter)

TABLE_CLASSES: dict[str, type[Table]] = {
    "camera": Camera,
    "emitter": Emitter,
    "surface": Surface,
    "defect": Defect,
    "render": RenderSettings,
    "sensor": Sensor,
    "part": Part,
}


def _rebuild_table(table: str, values: dict[str, Any]) -> Table:
    return TABLE_CLASSES[table](**values)


# --------------------------------------------------------------------------- scene
@dataclass(frozen=True)
class Scene:
    """A whole deflectometry set-up; the unit a renderer turns into a frame."""

    camera: Camera = field(default_factory=Camera)
    emitter: Emitter = field(default_factory=Emitter)
    surface: Surface = field(default_factory=Surface)
    defect: Defect = field(default_factory=Defect)
    render: RenderSettings = field(default_factory=RenderSettings)
    sensor: Sensor = field(default_factory=Sensor)
    part: Part = field(default_factory=Part)
    #: What the station believes of itself where it differs from the truth: ``(dotted
    #: path, value)`` pairs, sorted (``[calibration]`` of a scene file). The frames are
    #: rendered from the scene; an instrument that reconstructs geometry (slopes,
    #: heights) uses :meth:`believed`.
    calibration: tuple[tuple[str, Any], ...] = ()

    def __post_init__(self) -> None:
        if self.emitter.period == "auto" or self.emitter.period_auto:
            fixed = replace(self.emitter, period=2.0, period_auto=False)
            period = auto_period_mm(replace(self, emitter=fixed))
            object.__setattr__(
                self, "emitter", replace(self.emitter, period=period, period_auto=True)
            )

    @cached_property
    def active(self) -> Active:
        """The component filling each slot, resolved once: what the composer, the
        renderer, the tracer and the metric ask."""
        return registry().active(self)

    def __getstate__(self) -> dict[str, Any]:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def __setstate__(self, state: dict[str, Any]) -> None:
        for name, value in state.items():
            object.__setattr__(self, name, value)

    # ----------------------------------------------------------------- geometry
    def emitter_plane(self) -> EmitterPlane:
        """The screen's plane in the part's frame (the frame the renderer, the oracle and
        the instruments work in; :mod:`glshade.scene.station`)."""
        return self.station.screen.in_frame(self.station.part)

    def camera_pose(self) -> CameraPose:
        """The camera's pose in the part's frame."""
        return self.station.camera.in_frame(self.station.part)

    @cached_property
    def gaze(self) -> Gaze:
        """The station's geometry at its gaze point as the closed forms read it
        (:class:`~glshade.scene.station.Gaze`; the rig's own numbers for the rig)."""
        return gaze_of(self)

    @cached_property
    def station(self) -> Station:
        """The camera, the screen and the part, posed in the world frame."""
        return station_of(self)

    def believed(self) -> Scene:
        """The station as it believes itself to be: the scene with its ``calibration``
        values (itself where it has none)."""
        if not self.calibration:
            return self
        return replace(self.with_values(self.calibration), calibration=())

    def with_calibration(self, pairs: Any) -> Scene:
        """A copy believing ``pairs`` (``(dotted path, value)``; an empty list: belief =
        truth), each checked as the scene would check it; a bad one raises a
        :class:`SceneError` naming ``calibration.<path>``."""
        believed = tuple(sorted(dict((str(p), _frozen(v)) for p, v in pairs).items()))
        scene = replace(self, calibration=believed)
        try:
            scene.believed()
        except SceneError as exc:
            raise SceneError(f"{CALIBRATION_TABLE}.{exc.field}", exc.allowed, exc.got) from None
        return scene

    def title(self) -> str:
        """The case in a few words, as figure titles name it (depth in µm)."""
        d = self.defect
        if d.isotropic:
            shape = f"σ² {d.sigma_x2:g} mm²"
        else:
            shape = f"Σ ({d.sigma_x2:g}, {d.sigma_z2:g}, {d.sigma_xz:g}) mm²"
        base = self.active.surface.describe(self)
        if is_rig(self):
            seen = f"θ {self.camera.theta_deg:g}°"
        else:  # a posed station: the camera's elevation seen from its gaze point
            seen = f"posed, θ {math.degrees(self.gaze.theta_rad):.3g}° at the gaze point"
        return f"{base}, {seen}, {shape}, dmax {d.dmax * 1000:g} µm"

    def local_origin(self) -> np.ndarray:
        """The centre of the local frame every shader computes in: the defect's centre
        (world mm, float64; a frame centred on the dent)."""
        return self.active.defect.centre(self)

    # ----------------------------------------------------------------- variants
    def without_defect(self) -> Scene:
        """The same scene with ``dmax = 0`` (the reference image of the visibility metric)."""
        return replace(self, defect=replace(self.defect, dmax=0.0))

    def with_phase(self, phase_mm: float) -> Scene:
        return replace(self, emitter=replace(self.emitter, phase=phase_mm))

    def with_size(self, size: int) -> Scene:
        """Same field of view on ``size`` pixels across."""
        return replace(self, camera=self.camera.resampled(size))

    def with_value(self, path: str, value: Any) -> Scene:
        """A copy with one parameter changed: ``scene.with_value("camera.theta_deg", 5)``."""
        return self.with_values([(path, value)])

    def with_values(self, pairs: Any) -> Scene:
        """A copy with dotted keys set, all at once (keys that only make sense together,
        a kind and its file, can be set together): ``[("camera.theta_deg", 5), ...]``.
        A value may be text with a unit (``"5 um"``). A named entry of a table of named
        numbers, ``("surface.parameters.a", 0.002)``, sets that entry and keeps the
        table's others."""
        tables: dict[str, dict[str, Any]] = {}
        for path, value in pairs:
            indexed = _indexed(path)
            if indexed is not None:
                whole, index = indexed
                given = tables.get(whole.table, {}).get(whole.key, self.value(whole.path))
                tables.setdefault(whole.table, {})[whole.key] = _with_component(
                    whole, given, index, value
                )
                continue
            entry = registry().entry(path)
            if entry is not None:
                param, name = entry
                given = tables.get(param.table, {}).get(param.key, self.value(param.path))
                current = dict(param.check(given))
                current[name] = value  # checked with the table (named as the entry)
                tables.setdefault(param.table, {})[param.key] = tuple(current.items())
                continue
            registry().param(path)  # unknown table or key: a SceneError naming it
            table, _, key = path.partition(".")
            tables.setdefault(table, {})[key] = value
        return self.updated(**tables) if tables else self

    def value(self, path: str) -> Any:
        """A parameter's value by its dotted path (``defect.sigma2`` of an anisotropic
        defect: None; an entry of a table, ``surface.parameters.a``, that it lacks: None)."""
        indexed = _indexed(path)
        if indexed is not None:
            whole, index = indexed
            vector = self.value(whole.path)
            return None if vector is None else vector[index]
        entry = registry().entry(path)
        if entry is not None:
            return dict(self.value(entry[0].path) or ()).get(entry[1])
        param = registry().param(path)
        table = getattr(self, param.table)
        if param.stored:
            return getattr(table, param.key)
        return _file_values(self, param.table, everything=True).get(param.key)

    def input_files(self) -> tuple[Path, ...]:
        """The files the scene reads (a height map's ``surface.file``), as the process
        reads them: what no output of a run may overwrite."""
        reg = registry()
        active = self.active
        found = []
        for param in reg.params():
            if param.value_type != "path" or not param.stored:
                continue
            if not any(owner in active for owner in reg.owners(param)):
                continue
            value = getattr(getattr(self, param.table), param.key)
            if isinstance(value, str) and value.strip():
                found.append(Path(value))
        return tuple(found)

    def updated(self, **tables: dict[str, Any]) -> Scene:
        """A copy with some keys of some tables replaced:
        ``scene.updated(camera={"theta_deg": 5})``.

        Keys use the scene-file names (``defect={"sigma2": 9}`` works too).
        """
        parts: dict[str, Any] = {}
        for table, changes in tables.items():
            if table not in TABLE_CLASSES:
                raise SceneError(table, "one of the tables " + ", ".join(TABLE_CLASSES))
            values = getattr(self, table).values()
            values.update(_read_file(table, dict(changes), current=values))
            parts[table] = TABLE_CLASSES[table](**values)
        return replace(self, **parts)

    # ----------------------------------------------------------------- files
    def to_dict(self) -> dict[str, dict[str, Any]]:
        """The TOML layout of a scene file: per table, the parameters of the components in
        use (and any other that differs from its default); unset values are left out and
        an isotropic defect is written as ``sigma2``."""
        tables: dict[str, Any] = {table: _file_values(self, table) for table in TABLE_CLASSES}
        written = {
            table: values for table, values in tables.items() if values or table in ALWAYS_WRITTEN
        }
        if self.calibration:
            written[CALIBRATION_TABLE] = {
                path: list(value) if isinstance(value, tuple) else value
                for path, value in self.calibration
            }
        return written

    def to_file_dict(
        self, folder: str | os.PathLike[str], climb: bool = False
    ) -> dict[str, dict[str, Any]]:
        """:meth:`to_dict` as a scene file in ``folder`` holds it: the files the scene reads
        (a height map) relative to ``folder`` where they lie under it, else absolute;
        ``climb``: relative wherever they lie (``../maps/bump.npy``), for a record that
        travels with its folder's tree."""
        return _relative_paths(self.to_dict(), Path(folder), climb)

    @classmethod
    def from_dict(cls, data: dict[str, Any], base: Path | None = None) -> Scene:
        """Build from the scene-file layout; missing keys take the paper's defaults,
        unknown tables or keys are an error. ``base``: the directory relative file paths
        (a height map's ``surface.file``) are read from. A ``[measure]`` table (how the
        scene is measured: :mod:`glshade.instruments.table`) is the file's, not the
        scene's: it is read where the scene is measured, not here."""
        if not isinstance(data, dict):
            raise SceneError("scene", "a table of tables (" + ", ".join(TABLE_CLASSES) + ")", data)
        parts: dict[str, Any] = {}
        for table, values in data.items():
            if table in (MEASURE_TABLE, CALIBRATION_TABLE):
                continue
            if table not in TABLE_CLASSES:
                raise SceneError(
                    table, "one of the tables " + ", ".join(TABLE_CLASSES) + " (unknown table)"
                )
            if not isinstance(values, dict):
                raise SceneError(table, "a table of keys", values)
            read = _read_file(table, _resolve_paths(table, dict(values), base))
            parts[table] = TABLE_CLASSES[table](**read)
        scene = cls(**parts)
        if CALIBRATION_TABLE in data:
            scene = scene.with_calibration(_calibration_pairs(data[CALIBRATION_TABLE]))
        return scene

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Scene:
        """Read a TOML scene file (``docs/scene-format.md``); any problem with the file
        (missing, a directory, unreadable, not UTF-8 text, not TOML, a wrong value) is a
        :class:`SceneError` whose one line names the file or the field."""
        return cls.from_dict(read_toml(Path(path)), base=Path(path).parent)

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the scene as TOML, atomically."""
        import tomli_w

        from glshade.files import atomic_write_bytes

        data = self.to_file_dict(Path(path).parent)
        atomic_write_bytes(Path(path), tomli_w.dumps(data).encode())


#: A scene file's table that says how its scene is measured (the instrument and its
#: settings), read by :func:`glshade.instruments.table.file_measure_table`.
MEASURE_TABLE = "measure"
#: A scene file's table of what the station believes of itself where it differs from the
#: truth (``[calibration]``: dotted paths, or tables of the scene's tables).
CALIBRATION_TABLE = "calibration"


def _calibration_pairs(table: Any, prefix: str = "") -> list[tuple[str, Any]]:
    """``[calibration]``'s entries as ``(dotted path, value)``: ``camera.focal = 25.1``
    and ``[calibration.camera] focal = 25.1`` say the same."""
    if not isinstance(table, dict):
        raise SceneError(CALIBRATION_TABLE, "a table of dotted parameter paths = values", table)
    pairs: list[tuple[str, Any]] = []
    for key, value in table.items():
        path = f"{prefix}{key}"
        if isinstance(value, dict):
            pairs += _calibration_pairs(value, path + ".")
        else:
            pairs.append((path, value))
    return pairs


def _frozen(value: Any) -> Any:
    return tuple(value) if isinstance(value, list) else value


def _indexed(path: str) -> tuple[Any, int] | None:
    """``(declaration of the whole vector, index)`` of a component path ``table.key[i]``
    (checked by :meth:`Registry.component`); None for any other path."""
    if not path.endswith("]") or "[" not in path:
        return None
    registry().component(path)  # a SceneError naming the path where it is no component
    whole, _, rest = path.partition("[")
    return registry().param(whole), int(rest[:-1])


def _with_component(param: Any, given: Any, index: int, value: Any) -> tuple[Any, ...]:
    """The vector ``given`` with component ``index`` set to ``value`` (an unset vector is
    refused: there are no other components to keep)."""
    if given is None:
        raise SceneError(param.path, f"set as a whole before {param.path}[{index}] is set")
    from glshade.units import parse_quantity

    number = (
        parse_quantity(value, param.unit, f"{param.path}[{index}]")
        if isinstance(value, str)
        else value
    )
    items = list(given)
    items[index] = number
    return tuple(items)


#: A scene file is a few hundred bytes; anything beyond this is not one.
MAX_SCENE_FILE_BYTES = 1 << 20
#: Leading bytes of files often given by mistake.
_MAGIC = (
    (b"\x89PNG", "a PNG image"),
    (b"II*\x00", "a TIFF image"),
    (b"MM\x00*", "a TIFF image"),
    (b"\xff\xd8\xff", "a JPEG image"),
    (b"\x93NUMPY", "a NumPy array"),
    (b"%PDF", "a PDF document"),
    (b"PK\x03\x04", "a zip archive"),
    (b"\x1f\x8b", "a gzip archive"),
    (b"\xff\xfe", "UTF-16 text"),
    (b"\xfe\xff", "UTF-16 text"),
)
_BOM = b"\xef\xbb\xbf"


def read_toml(path: Path, what: str = "scene file") -> dict[str, Any]:
    """A scene file's (or another ``what``'s) TOML tables. A UTF-8 byte-order mark (which
    TOML does not allow, and Windows editors write) is skipped; every other problem is a
    :class:`SceneError` naming the file."""
    field = f"{what} {path}"
    raw = _read_scene_bytes(Path(path), what)
    if len(raw) > MAX_SCENE_FILE_BYTES:
        raise SceneError(
            field, f"a TOML file of at most {MAX_SCENE_FILE_BYTES >> 20} MiB (this one is larger)"
        )
    kind = next((name for magic, name in _MAGIC if raw.startswith(magic)), None)
    if kind is not None:
        raise SceneError(field, f"a TOML text file (this is {kind})")
    raw = raw.removeprefix(_BOM)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise SceneError(
            field,
            f"UTF-8 text (byte 0x{raw[exc.start]:02x} on line {line} is not UTF-8; "
            "re-save the file as UTF-8)",
        ) from None
    if "\x00" in text:
        raise SceneError(field, "a TOML text file (it holds NUL bytes: binary data)")
    import tomllib  # only a scene file needs the TOML parser (and its datetime)

    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(field, f"valid TOML ({exc})") from None
    except RecursionError:
        raise SceneError(field, "TOML nested at most a few hundred levels deep") from None
    except ValueError:  # an integer of more digits than Python converts (4300)
        raise SceneError(field, "valid TOML (it holds an integer of thousands of digits)") from None
    return data


def _read_scene_bytes(path: Path, what: str) -> bytes:
    """The first ``MAX_SCENE_FILE_BYTES + 1`` bytes of a scene file, read only from a
    regular file (a FIFO or a device is refused without waiting on it)."""
    from glshade.files import note_input, open_regular

    text = os.fspath(path)
    if "\0" in text:
        raise SceneError(what, "a path without NUL bytes", text)
    if not os.path.lexists(text):
        raise SceneError(what, "an existing TOML file", text)
    if os.path.isdir(text):
        raise SceneError(f"{what} {path}", "a TOML file, not a directory")
    try:
        fd = open_regular(text, what)
    except GlshadeError as exc:
        raise SceneError(f"{what} {path}", f"a readable TOML file ({_reason(exc)})") from None
    note_input(text, fd)  # a file this run reads: never one of its outputs
    try:
        with os.fdopen(fd, "rb") as fh:
            return fh.read(MAX_SCENE_FILE_BYTES + 1)
    except OSError as exc:
        raise SceneError(f"{what} {path}", f"a readable TOML file ({exc.strerror})") from None


def _reason(exc: GlshadeError) -> str:
    """The reason of a :func:`glshade.files.open_regular` error, without its path."""
    return str(exc).rpartition(": ")[2] if ": " in str(exc) else str(exc)


def _resolve_paths(table: str, values: dict[str, Any], base: Path | None) -> dict[str, Any]:
    """File paths of a scene file, relative to its directory -> as the process reads them."""
    if base is None:
        return values
    for key, value in values.items():
        param = registry().table_params(table)
        declared = next((p for p in param if p.key == key), None)
        if (
            declared is not None
            and declared.value_type == "path"
            and isinstance(value, str)
            and value.strip()
        ):
            values[key] = str(base / value) if not os.path.isabs(value) else value
    return values


def _relative_paths(
    data: dict[str, dict[str, Any]], base: Path, climb: bool = False
) -> dict[str, dict[str, Any]]:
    """File paths written relative to the scene file's directory where they lie under it
    (``climb``: wherever they lie)."""
    for table, values in data.items():
        for param in registry().table_params(table):
            value = values.get(param.key)
            if param.value_type == "path" and isinstance(value, str) and climb:
                values[param.key] = os.path.relpath(os.path.abspath(value), os.path.abspath(base))
            elif param.value_type == "path" and isinstance(value, str):
                try:
                    values[param.key] = str(
                        Path(os.path.abspath(value)).relative_to(os.path.abspath(base))
                    )
                except ValueError:
                    values[param.key] = os.path.abspath(value)
    return data


def _read_file(
    table: str, values: dict[str, Any], current: dict[str, Any] | None = None
) -> dict[str, Any]:
    """Scene-file keys of one table -> its fields: the components' shorthands expanded,
    every key checked to be declared. ``current``: the values being changed, if any."""
    reg = registry()
    for key, value in values.items():  # as typed: an error names the key the user wrote
        typed = next((p for p in reg.table_params(table) if p.key == key), None)
        if typed is not None and typed.value_type != "choice":
            values[key] = typed.check(value)
    for component in _table_components(table):
        values = component.read_file(values, current)
    declared = [p.key for p in reg.table_params(table)]
    stored = {p.key for p in reg.table_params(table) if p.stored}
    for key in values:
        if key not in stored:
            raise SceneError(
                f"{table}.{key}", "one of the keys " + ", ".join(declared) + " (unknown key)"
            )
    return values


def _file_values(scene: Scene, table: str, everything: bool = False) -> dict[str, Any]:
    """One table as a scene file writes it (``everything``: inactive parameters too)."""
    reg = registry()
    active = scene.active
    values = {}
    given = getattr(scene, table).values()  # as the scene was given ("auto" stays "auto")
    for param in reg.table_params(table):
        if not param.stored:
            continue
        value = given[param.key]
        in_use = reg.choices(param) is not None or any(
            owner in active for owner in reg.owners(param)
        )
        if value is None or not (everything or in_use or value != param.default):
            continue
        if param.quiet and not everything and value == param.default:
            continue
        values[param.key] = (
            list(value)
            if param.value_type in ("pair", "vector", "names")
            else dict(value)
            if param.value_type == "table"
            else value
        )
    for component in _table_components(table):
        values = component.write_file(values)
    return values


def _table_components(table: str):
    return registry().table_components(table)
