"""The scene model: camera, stripe emitter, surface, defect, render settings.

Conventions are those of ``SPEC.md`` (world frame with the gazing point at the origin,
``+y`` up, plane of incidence ``yz``, camera on ``+z``, emitter on ``-z``). Every length is
in millimetres, every angle that crosses the user boundary in degrees.

A scene is five tables. A table's fields are not written here: they are the parameters
the registered components declare for it (:mod:`glshade.components.registry`), so a new
component's parameters join its table, its validation and its TOML without an edit
here. Each table is a frozen dataclass generated from those declarations (``Camera(...)``
builds one; ``dataclasses.replace`` works) that validates itself on construction: a
value out of range raises :class:`~glshade.errors.SceneError` naming the field as a
scene file spells it (``camera.theta_deg``) and the allowed range.
``Scene.from_dict`` / ``Scene.to_dict`` map to and from the TOML layout of SPEC §8 and
round-trip.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
import tomllib
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from glshade.components.registry import registry
from glshade.errors import SceneError

#: The tables SPEC §8 lists for the paper's model: written even when empty (a table
#: that switches something on by its presence, ``[sensor]``, is written only when on).
PAPER_TABLES: tuple[str, ...] = ("camera", "emitter", "surface", "defect", "render")
#: The paper's three surfaces (its study runs over them).
PAPER_SURFACES: tuple[str, ...] = ("flat", "cylinder", "sphere")
#: Stripe periods the paper uses where they are not the Emitter default (2 mm), mm.
PAPER_PERIOD_MM: dict[str, float] = {"sphere": 10.0}


# --------------------------------------------------------------------------- tables
class Table:
    """Base of the scene's tables. ``Camera(theta_deg=5)`` returns an instance of a
    frozen dataclass generated from the parameters registered for the table now; its
    ``__post_init__`` checks each value against its declaration, then the components'
    checks over several values."""

    table: ClassVar[str]

    def __new__(cls, *args: Any, **kwargs: Any) -> Table:
        if "__dataclass_fields__" in cls.__dict__:
            generated = cls
        else:
            generated = _fields_class(
                cls, tuple(p for p in registry().table_params(cls.table) if p.stored)
            )
        return object.__new__(generated)

    def __post_init__(self) -> None:
        reg = registry()
        values = {}
        for param in reg.table_params(self.table):
            if param.stored:
                value = param.check(getattr(self, param.key), reg.choices(param))
                object.__setattr__(self, param.key, value)
                values[param.key] = value
        for check in reg.checks(self.table):
            check(values)

    def values(self) -> dict[str, Any]:
        """Field name -> value, in declaration order."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def replace(self, **changes: Any) -> Table:
        """A copy with some fields changed (validated)."""
        return replace(self, **changes)

    def __reduce__(self):
        return _rebuild_table, (self.table, self.values())


@functools.lru_cache(maxsize=64)
def _fields_class(public: type, params: tuple) -> type:
    """The dataclass of ``public``'s table with these (stored) parameters as fields: one
    class per set of declarations, so tables made before and after a plug-in came and
    went compare equal."""
    spec = [(p.key, object, field(default=p.default)) for p in params]
    generated = dataclasses.make_dataclass(public.__name__, spec, bases=(public,), frozen=True)
    generated.__module__ = public.__module__
    generated.__qualname__ = public.__qualname__
    generated.__doc__ = public.__doc__
    return generated


def _rebuild_table(table: str, values: dict[str, Any]) -> Table:
    return TABLE_CLASSES[table](**values)


def rig_rotation(azimuth_rad: float) -> np.ndarray:
    """Rotation about +y by ``azimuth_rad`` (+z towards +x), float64 3x3."""
    c, s = math.cos(azimuth_rad), math.sin(azimuth_rad)
    if azimuth_rad == 0.0:
        return np.eye(3)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


class Camera(Table):
    """Where the camera is and what its sensor is (SPEC §2): ``theta_deg``,
    ``distance`` (mm, origin to principal point), ``focal`` (mm), ``pixel_pitch`` (mm),
    ``width`` x ``height`` pixels, and what the camera component declares beyond."""

    table = "camera"

    @property
    def theta_rad(self) -> float:
        return math.radians(self.theta_deg)

    @property
    def azimuth_rad(self) -> float:
        return math.radians(self.azimuth_deg)

    def rig_rotation(self) -> np.ndarray:
        """3x3 rotation of the rig (camera and emitter) about +y by ``azimuth_deg``: +z
        turns towards +x (float64). The identity at azimuth 0, SPEC's frame."""
        return rig_rotation(self.azimuth_rad)

    def position(self) -> np.ndarray:
        """Principal point ``C = distance R (0, sin θ, cos θ)`` in mm (float64), ``R`` the
        rig's rotation (:meth:`rig_rotation`)."""
        th = self.theta_rad
        return self.rig_rotation() @ (self.distance * np.array([0.0, math.sin(th), math.cos(th)]))

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Unit vectors ``(forward, right, up)`` of the camera, float64."""
        th = self.theta_rad
        turn = self.rig_rotation()
        forward = turn @ -np.array([0.0, math.sin(th), math.cos(th)])
        up = turn @ np.array([0.0, math.cos(th), -math.sin(th)])
        right = np.cross(forward, up)
        return forward, right, up

    def view_matrix(self) -> np.ndarray:
        """World -> camera 4x4 matrix (pyrr's look-at, row-vector convention), float64.

        Its first three columns hold ``right``, ``up`` and ``-forward``; the viewer and
        anything that projects world points into the image use it.
        """
        import pyrr

        _, _, up = self.basis()
        return np.asarray(pyrr.Matrix44.look_at(self.position(), np.zeros(3), up, dtype=np.float64))

    def resampled(self, size: int) -> Camera:
        """The same field of view on ``size`` pixels across (SPEC §2, ``--size N``).

        The pitch becomes ``pixel_pitch * width / size``; the height keeps the aspect.
        """
        size = registry().param("camera.width").check(size)
        height = max(1, round(self.height * size / self.width))
        return replace(
            self, width=size, height=height, pixel_pitch=self.pixel_pitch * self.width / size
        )


class Emitter(Table):
    """The stripe emitter (SPEC §3): ``distance``, ``period``, ``stripe_sigma`` (None:
    FWHM = half a period), ``phase``, ``half_size`` (mm)."""

    table = "emitter"

    @property
    def sigma_mm(self) -> float:
        """The stripe's Gaussian width in mm (the default when ``stripe_sigma`` is unset)."""
        from glshade.components.emitter_stripes import STRIPE_SIGMA_PER_PERIOD

        return (
            self.stripe_sigma
            if self.stripe_sigma is not None
            else self.period * STRIPE_SIGMA_PER_PERIOD
        )


class Surface(Table):
    """The base surface ``y = f(x, z)`` (SPEC §4): ``kind`` names the surface component;
    the others (``radius``, ``axis``, …) are the parameters the kinds declare."""

    table = "surface"

    @property
    def concave(self) -> bool:
        """Curved upwards somewhere at the gaze point (a bowl, a trough)."""
        component = registry().get("surface", self.kind)
        return any(f2 > 0.0 for f2 in component.second_derivatives(Scene(surface=self)))


class Defect(Table):
    """The defect (paper eq. 2): ``dmax`` (mm; > 0 dent, < 0 bump, 0 none), the covariance
    ``sigma_x2``, ``sigma_z2``, ``sigma_xz`` (mm², positive definite), the centre ``x0``,
    ``z0`` (mm)."""

    table = "defect"

    @classmethod
    def isotropic_dent(cls, dmax: float, sigma2: float, x0: float = 0.0, z0: float = 0.0) -> Defect:
        return cls(dmax=dmax, sigma_x2=sigma2, sigma_z2=sigma2, sigma_xz=0.0, x0=x0, z0=z0)

    @property
    def present(self) -> bool:
        return self.dmax != 0.0

    @property
    def isotropic(self) -> bool:
        return self.sigma_xz == 0.0 and self.sigma_x2 == self.sigma_z2

    def inverse_covariance(self) -> tuple[float, float, float]:
        """``(a, b, c)`` with ``Σ^-1 = [[a, b], [b, c]]`` in 1/mm², float64."""
        det = self.sigma_x2 * self.sigma_z2 - self.sigma_xz * self.sigma_xz
        return self.sigma_z2 / det, -self.sigma_xz / det, self.sigma_x2 / det


class RenderSettings(Table):
    """How a frame is computed (SPEC §5, §8 ``[render]``): ``precision``, ``supersample``,
    ``reflection`` (names the reflection component) and its parameters."""

    table = "render"


class Sensor(Table):
    """The camera's sensor (SPEC §8.2 ``[sensor]``): off (``full_well_e`` unset, the
    noiseless float radiance) unless a scene file has the table or a key of it is set."""

    table = "sensor"

    @property
    def on(self) -> bool:
        return self.full_well_e is not None


TABLE_CLASSES: dict[str, type[Table]] = {
    "camera": Camera,
    "emitter": Emitter,
    "surface": Surface,
    "defect": Defect,
    "render": RenderSettings,
    "sensor": Sensor,
}


# --------------------------------------------------------------------------- scene
@dataclass(frozen=True)
class EmitterFrame:
    """The emitter plane in world coordinates (float64): centre, normal, in-plane axes."""

    centre: np.ndarray
    normal: np.ndarray
    e_u: np.ndarray
    e_v: np.ndarray


@dataclass(frozen=True)
class Scene:
    """A whole deflectometry set-up; the unit a renderer turns into a frame."""

    camera: Camera = field(default_factory=Camera)
    emitter: Emitter = field(default_factory=Emitter)
    surface: Surface = field(default_factory=Surface)
    defect: Defect = field(default_factory=Defect)
    render: RenderSettings = field(default_factory=RenderSettings)
    sensor: Sensor = field(default_factory=Sensor)

    # ----------------------------------------------------------------- geometry
    def emitter_frame(self) -> EmitterFrame:
        """``E = distance (0, sin θ, -cos θ)``, ``n_E = -E/|E|``, ``e_u = x``, ``e_v`` (SPEC §3),
        all turned with the camera by the rig's azimuth (:meth:`Camera.rig_rotation`)."""
        th = self.camera.theta_rad
        turn = self.camera.rig_rotation()
        direction = turn @ np.array([0.0, math.sin(th), -math.cos(th)])
        return EmitterFrame(
            centre=self.emitter.distance * direction,
            normal=-direction,
            e_u=turn @ np.array([1.0, 0.0, 0.0]),
            e_v=turn @ np.array([0.0, math.cos(th), math.sin(th)]),
        )

    def title(self) -> str:
        """The case in a few words, as figure titles name it (depth in µm)."""
        d = self.defect
        shape = (
            f"σ² {d.sigma_x2:g} mm²"
            if d.isotropic
            else f"Σ ({d.sigma_x2:g}, {d.sigma_z2:g}, {d.sigma_xz:g}) mm²"
        )
        base = registry().active(self).surface.describe(self)
        return f"{base}, θ {self.camera.theta_deg:g}°, {shape}, dmax {d.dmax * 1000:g} µm"

    def local_origin(self) -> np.ndarray:
        """The centre of the local frame every shader computes in: the defect's centre
        (world mm, float64; SPEC §5, a frame centred on the dent)."""
        return registry().active(self).defect.centre(self)

    # ----------------------------------------------------------------- variants
    def without_defect(self) -> Scene:
        """The same scene with ``dmax = 0`` (the reference image of the visibility metric)."""
        return replace(self, defect=replace(self.defect, dmax=0.0))

    def with_phase(self, phase_mm: float) -> Scene:
        return replace(self, emitter=replace(self.emitter, phase=phase_mm))

    def with_size(self, size: int) -> Scene:
        """Same field of view on ``size`` pixels across (SPEC §2)."""
        return replace(self, camera=self.camera.resampled(size))

    def with_value(self, path: str, value: Any) -> Scene:
        """A copy with one parameter changed: ``scene.with_value("camera.theta_deg", 5)``."""
        table, _, key = path.partition(".")
        registry().param(path)  # unknown table or key: a SceneError naming it
        return self.updated(**{table: {key: value}})

    def value(self, path: str) -> Any:
        """A parameter's value by its dotted path (``defect.sigma2`` of an anisotropic
        defect: None)."""
        param = registry().param(path)
        table = getattr(self, param.table)
        if param.stored:
            return getattr(table, param.key)
        return _file_values(self, param.table, everything=True).get(param.key)

    def updated(self, **tables: dict[str, Any]) -> Scene:
        """A copy with some keys of some tables replaced: ``scene.updated(camera={"theta_deg": 5})``.

        Keys use the scene-file names (``defect={"sigma2": 9}`` works too).
        """
        parts = {}
        for table, changes in tables.items():
            if table not in TABLE_CLASSES:
                raise SceneError(table, "one of the tables " + ", ".join(TABLE_CLASSES))
            values = getattr(self, table).values()
            values.update(_read_file(table, dict(changes), current=values))
            parts[table] = TABLE_CLASSES[table](**values)
        return replace(self, **parts)

    # ----------------------------------------------------------------- files
    def to_dict(self) -> dict[str, dict[str, Any]]:
        """The TOML layout of SPEC §8: per table, the parameters of the components in use
        (and any other that differs from its default); unset values are left out and an
        isotropic defect is written as ``sigma2``."""
        tables = {table: _file_values(self, table) for table in TABLE_CLASSES}
        return {
            table: values for table, values in tables.items() if values or table in PAPER_TABLES
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any], base: Path | None = None) -> Scene:
        """Build from the SPEC §8 layout; missing keys take the paper's defaults, unknown
        tables or keys are an error. ``base``: the directory relative file paths (a height
        map's ``surface.file``) are read from."""
        if not isinstance(data, dict):
            raise SceneError("scene", "a table of tables (" + ", ".join(TABLE_CLASSES) + ")", data)
        parts: dict[str, Any] = {}
        for table, values in data.items():
            if table not in TABLE_CLASSES:
                raise SceneError(
                    table, "one of the tables " + ", ".join(TABLE_CLASSES) + " (unknown table)"
                )
            if not isinstance(values, dict):
                raise SceneError(table, "a table of keys", values)
            parts[table] = TABLE_CLASSES[table](
                **_read_file(table, _resolve_paths(table, dict(values), base))
            )
        return cls(**parts)

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

        data = _relative_paths(self.to_dict(), Path(path).parent)
        atomic_write_bytes(Path(path), tomli_w.dumps(data).encode())


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
    try:
        with path.open("rb") as fh:
            raw = fh.read(MAX_SCENE_FILE_BYTES + 1)
    except FileNotFoundError:
        raise SceneError(what, "an existing TOML file", str(path)) from None
    except IsADirectoryError:
        raise SceneError(field, "a TOML file, not a directory") from None
    except OSError as exc:
        raise SceneError(field, f"a readable TOML file ({exc.strerror or exc})") from None
    except ValueError:  # a NUL byte in the path
        raise SceneError(what, "a path without NUL bytes", str(path)) from None
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
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(field, f"valid TOML ({exc})") from None
    return data


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


def _relative_paths(data: dict[str, dict[str, Any]], base: Path) -> dict[str, dict[str, Any]]:
    """File paths written relative to the scene file's directory where they lie under it."""
    for table, values in data.items():
        for param in registry().table_params(table):
            value = values.get(param.key)
            if param.value_type == "path" and isinstance(value, str):
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
    active = reg.active(scene)
    values = {}
    for param in reg.table_params(table):
        if not param.stored:
            continue
        value = getattr(getattr(scene, table), param.key)
        in_use = reg.choices(param) is not None or any(
            owner in active for owner in reg.owners(param)
        )
        if value is None or not (everything or in_use or value != param.default):
            continue
        values[param.key] = (
            list(value)
            if param.value_type in ("pair", "vector")
            else dict(value)
            if param.value_type == "table"
            else value
        )
    for component in _table_components(table):
        values = component.write_file(values)
    return values


def _table_components(table: str):
    reg = registry()
    return tuple(
        c for slot in reg.slots() if slot.table == table for c in reg.components(slot.name)
    )


# --------------------------------------------------------------------------- paper
def paper_scene(
    surface: str = "flat",
    theta_deg: float = 45.0,
    sigma2: float = 4.0,
    dmax: float = 0.005,
    phase: float = 0.0,
) -> Scene:
    """The paper's geometry (Table 1, section III): camera 175.6 mm, emitter 256 mm,
    1024² pixels of 5 µm, f = 25 mm; cylinder and sphere R = 70 mm; sphere period 10 mm."""
    if surface not in PAPER_SURFACES:
        raise SceneError(
            "surface.kind",
            "one of " + ", ".join(PAPER_SURFACES) + " (the paper's surfaces)",
            surface,
        )
    period = PAPER_PERIOD_MM.get(surface, Emitter().period)
    return Scene(
        camera=Camera(theta_deg=theta_deg),
        emitter=Emitter(period=period, phase=phase),
        surface=Surface(kind=surface, radius=70.0, axis="z"),
        defect=Defect.isotropic_dent(dmax=dmax, sigma2=sigma2),
    )
