"""The scene model: camera, stripe emitter, surface, Gaussian defect, render settings.

Conventions are those of ``SPEC.md`` (world frame with the gazing point at the origin,
``+y`` up, plane of incidence ``yz``, camera on ``+z``, emitter on ``-z``). Every length is
in millimetres, every angle that crosses the user boundary in degrees.

All classes are small frozen dataclasses that validate themselves on construction; a
value out of range raises :class:`~glshade.errors.SceneError` naming the field as it is
spelled in a scene file (``camera.theta_deg``) and the allowed range. ``Scene.from_dict``
/ ``Scene.to_dict`` map to and from the TOML layout of SPEC §8 and round-trip.
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np

from glshade.errors import SceneError

SurfaceKind = Literal["flat", "cylinder", "sphere"]
SURFACE_KINDS: tuple[str, ...] = ("flat", "cylinder", "sphere")
CYLINDER_AXES: tuple[str, ...] = ("z", "x")
PRECISIONS: tuple[str, ...] = ("fp32", "fp64")
REFLECTIONS: tuple[str, ...] = ("mirror", "blinn-phong")
MAX_SUPERSAMPLE = 16
MAX_IMAGE_SIDE = 16384

#: FWHM of one stripe = half a period  =>  sigma = period / (4 sqrt(2 ln 2)).
STRIPE_SIGMA_PER_PERIOD = 1.0 / (4.0 * math.sqrt(2.0 * math.log(2.0)))


# --------------------------------------------------------------------------- checks
def _number(table: str, name: str, value: Any) -> float:
    """A finite real number (bool is not a number here)."""
    where = f"{table}.{name}"
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise SceneError(where, "a finite number", value)
    value = float(value)
    if not math.isfinite(value):
        raise SceneError(where, "a finite number", value)
    return value


def _positive(table: str, name: str, value: Any) -> float:
    value = _number(table, name, value)
    if value <= 0.0:
        raise SceneError(f"{table}.{name}", "a finite number > 0", value)
    return value


def _integer(table: str, name: str, value: Any, lo: int, hi: int) -> int:
    where = f"{table}.{name}"
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        else:
            raise SceneError(where, f"an integer in [{lo}, {hi}]", value)
    value = int(value)
    if not lo <= value <= hi:
        raise SceneError(where, f"an integer in [{lo}, {hi}]", value)
    return value


def _choice(table: str, name: str, value: Any, allowed: tuple[str, ...]) -> str:
    if value not in allowed:
        raise SceneError(f"{table}.{name}", "one of " + ", ".join(allowed), value)
    return value


def _set(obj: object, name: str, value: Any) -> None:
    """Store a normalised value on a frozen dataclass during ``__post_init__``."""
    object.__setattr__(obj, name, value)


# --------------------------------------------------------------------------- tables
@dataclass(frozen=True)
class Camera:
    """Pinhole camera looking at the origin from elevation ``theta_deg`` (SPEC §2).

    ``distance`` (mm) is origin to principal point, ``focal`` (mm) the focal length,
    ``pixel_pitch`` (mm) the sensor pitch, ``width`` x ``height`` the sensor in pixels.
    """

    theta_deg: float = 45.0
    distance: float = 175.6
    focal: float = 25.0
    pixel_pitch: float = 0.005
    width: int = 1024
    height: int = 1024

    def __post_init__(self) -> None:
        t = "camera"
        theta = _number(t, "theta_deg", self.theta_deg)
        if not 0.0 < theta < 90.0:
            raise SceneError(f"{t}.theta_deg", "in (0, 90) degrees", theta)
        _set(self, "theta_deg", theta)
        for name in ("distance", "focal", "pixel_pitch"):
            _set(self, name, _positive(t, name, getattr(self, name)))
        for name in ("width", "height"):
            _set(self, name, _integer(t, name, getattr(self, name), 1, MAX_IMAGE_SIDE))

    @property
    def theta_rad(self) -> float:
        return math.radians(self.theta_deg)

    def position(self) -> np.ndarray:
        """Principal point ``C = distance (0, sin θ, cos θ)`` in mm (float64)."""
        th = self.theta_rad
        return self.distance * np.array([0.0, math.sin(th), math.cos(th)])

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Unit vectors ``(forward, right, up)`` of the camera, float64."""
        th = self.theta_rad
        forward = -np.array([0.0, math.sin(th), math.cos(th)])
        up = np.array([0.0, math.cos(th), -math.sin(th)])
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
        size = _integer("camera", "width", size, 1, MAX_IMAGE_SIDE)
        height = max(1, round(self.height * size / self.width))
        return replace(self, width=size, height=height, pixel_pitch=self.pixel_pitch * self.width / size)


@dataclass(frozen=True)
class Emitter:
    """Stripe emitter in the mirror position of the camera (SPEC §3).

    ``distance`` (mm) origin to centre, ``period`` (mm) stripe spacing, ``stripe_sigma``
    (mm) Gaussian width of one stripe (``None``: FWHM = half a period), ``phase`` (mm)
    shift along ``v``, ``half_size`` (mm) half extents in ``u`` and ``v``.
    """

    distance: float = 256.0
    period: float = 2.0
    stripe_sigma: float | None = None
    phase: float = 0.0
    half_size: tuple[float, float] = (150.0, 150.0)

    def __post_init__(self) -> None:
        t = "emitter"
        for name in ("distance", "period"):
            _set(self, name, _positive(t, name, getattr(self, name)))
        if self.stripe_sigma is not None:
            _set(self, "stripe_sigma", _positive(t, "stripe_sigma", self.stripe_sigma))
        _set(self, "phase", _number(t, "phase", self.phase))
        hs = self.half_size
        if isinstance(hs, (str, bytes)) or not hasattr(hs, "__len__") or len(hs) != 2:
            raise SceneError(f"{t}.half_size", "two numbers [u, v] > 0 (mm)", hs)
        _set(self, "half_size", (_positive(t, "half_size", hs[0]), _positive(t, "half_size", hs[1])))

    @property
    def sigma_mm(self) -> float:
        """The stripe's Gaussian width in mm (the default when ``stripe_sigma`` is unset)."""
        return self.stripe_sigma if self.stripe_sigma is not None else self.period * STRIPE_SIGMA_PER_PERIOD


@dataclass(frozen=True)
class Surface:
    """Base surface ``y = f(x, z)`` (SPEC §4).

    ``kind``: flat, cylinder or sphere; ``radius`` (mm, negative = concave) for the
    curved kinds; ``axis``: the cylinder's axis, ``z`` (in the plane of incidence) or ``x``.
    """

    kind: str = "flat"
    radius: float = 70.0
    axis: str = "z"

    def __post_init__(self) -> None:
        t = "surface"
        _choice(t, "kind", self.kind, SURFACE_KINDS)
        radius = _number(t, "radius", self.radius)
        if radius == 0.0:
            raise SceneError(f"{t}.radius", "non-zero (mm; negative = concave)", radius)
        _set(self, "radius", radius)
        _choice(t, "axis", self.axis, CYLINDER_AXES)

    @property
    def concave(self) -> bool:
        return self.kind != "flat" and self.radius < 0.0


@dataclass(frozen=True)
class Defect:
    """Gaussian dent of paper eq. 2, ``D = -dmax exp(-1/2 p^T Σ^-1 p)``, ``p = (x-x0, z-z0)``.

    ``dmax`` (mm): > 0 dent, < 0 bump, 0 none. ``Σ = [[sigma_x2, sigma_xz], [sigma_xz,
    sigma_z2]]`` (mm²) must be positive definite. ``x0``, ``z0`` (mm): the centre.
    """

    dmax: float = 0.005
    sigma_x2: float = 4.0
    sigma_z2: float = 4.0
    sigma_xz: float = 0.0
    x0: float = 0.0
    z0: float = 0.0

    def __post_init__(self) -> None:
        t = "defect"
        _set(self, "dmax", _number(t, "dmax", self.dmax))
        for name in ("sigma_x2", "sigma_z2"):
            _set(self, name, _positive(t, name, getattr(self, name)))
        sxz = _number(t, "sigma_xz", self.sigma_xz)
        if sxz * sxz >= self.sigma_x2 * self.sigma_z2:
            raise SceneError(
                f"{t}.sigma_xz",
                f"|sigma_xz| < sqrt(sigma_x2*sigma_z2) = {math.sqrt(self.sigma_x2 * self.sigma_z2):.6g} "
                "(covariance positive definite)",
                sxz,
            )
        _set(self, "sigma_xz", sxz)
        for name in ("x0", "z0"):
            _set(self, name, _number(t, name, getattr(self, name)))

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


@dataclass(frozen=True)
class RenderSettings:
    """How a frame is computed (SPEC §5, §8 ``[render]``).

    ``precision``: fp32 (default) or fp64 (the GPU-side reference); ``supersample``:
    rays per pixel side (1 … 16); ``reflection``: mirror or blinn-phong;
    ``shininess``: the Blinn-Phong exponent n (> 0).
    """

    precision: str = "fp32"
    supersample: int = 1
    reflection: str = "mirror"
    shininess: float = 1000.0

    def __post_init__(self) -> None:
        t = "render"
        _choice(t, "precision", self.precision, PRECISIONS)
        _set(self, "supersample", _integer(t, "supersample", self.supersample, 1, MAX_SUPERSAMPLE))
        _choice(t, "reflection", self.reflection, REFLECTIONS)
        _set(self, "shininess", _positive(t, "shininess", self.shininess))


_TABLES: dict[str, type] = {
    "camera": Camera,
    "emitter": Emitter,
    "surface": Surface,
    "defect": Defect,
    "render": RenderSettings,
}


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

    # ----------------------------------------------------------------- geometry
    def emitter_frame(self) -> EmitterFrame:
        """``E = distance (0, sin θ, -cos θ)``, ``n_E = -E/|E|``, ``e_u = x``, ``e_v`` (SPEC §3)."""
        th = self.camera.theta_rad
        direction = np.array([0.0, math.sin(th), -math.cos(th)])
        return EmitterFrame(
            centre=self.emitter.distance * direction,
            normal=-direction,
            e_u=np.array([1.0, 0.0, 0.0]),
            e_v=np.array([0.0, math.cos(th), math.sin(th)]),
        )

    def title(self) -> str:
        """The case in a few words, as figure titles name it (depth in µm)."""
        d, surface = self.defect, self.surface
        shape = f"σ² {d.sigma_x2:g} mm²" if d.isotropic else f"Σ ({d.sigma_x2:g}, {d.sigma_z2:g}, {d.sigma_xz:g}) mm²"
        base = "flat" if surface.kind == "flat" else f"{surface.kind} R {surface.radius:g} mm"
        if surface.kind == "cylinder":
            base += f" axis {surface.axis}"
        return f"{base}, θ {self.camera.theta_deg:g}°, {shape}, dmax {d.dmax * 1000:g} µm"

    # ----------------------------------------------------------------- variants
    def without_defect(self) -> Scene:
        """The same scene with ``dmax = 0`` (the reference image of the visibility metric)."""
        return replace(self, defect=replace(self.defect, dmax=0.0))

    def with_phase(self, phase_mm: float) -> Scene:
        return replace(self, emitter=replace(self.emitter, phase=phase_mm))

    def with_size(self, size: int) -> Scene:
        """Same field of view on ``size`` pixels across (SPEC §2)."""
        return replace(self, camera=self.camera.resampled(size))

    def updated(self, **tables: dict[str, Any]) -> Scene:
        """A copy with some keys of some tables replaced: ``scene.updated(camera={"theta_deg": 5})``.

        Keys use the scene-file names (``defect={"sigma2": 9}`` works too).
        """
        data = self.to_dict()
        for table, values in tables.items():
            if table not in _TABLES:
                raise SceneError(table, "one of the tables " + ", ".join(_TABLES))
            if table == "defect" and "sigma2" in values:
                for k in ("sigma_x2", "sigma_z2", "sigma_xz", "sigma2"):
                    data["defect"].pop(k, None)
            if table == "defect" and "sigma2" in data["defect"] and {"sigma_x2", "sigma_z2", "sigma_xz"} & set(values):
                s2 = data["defect"].pop("sigma2")  # an isotropic defect, one component edited
                data["defect"].update(sigma_x2=s2, sigma_z2=s2, sigma_xz=0.0)
            data[table].update(values)
        return Scene.from_dict(data)

    # ----------------------------------------------------------------- files
    def to_dict(self) -> dict[str, dict[str, Any]]:
        """The TOML layout of SPEC §8 (isotropic defects are written as ``sigma2``)."""
        out: dict[str, dict[str, Any]] = {}
        for name in _TABLES:
            table = asdict(getattr(self, name))
            if name == "emitter":
                table["half_size"] = list(table["half_size"])
                if table["stripe_sigma"] is None:
                    del table["stripe_sigma"]
            out[name] = table
        d = out["defect"]
        if self.defect.isotropic:
            sigma2 = d.pop("sigma_x2")
            del d["sigma_z2"], d["sigma_xz"]
            out["defect"] = {"dmax": d["dmax"], "sigma2": sigma2, "x0": d["x0"], "z0": d["z0"]}
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Scene:
        """Build from the SPEC §8 layout; missing keys take the paper's defaults, unknown
        tables or keys are an error."""
        if not isinstance(data, dict):
            raise SceneError("scene", "a table of tables (camera, emitter, surface, defect, render)", data)
        parts: dict[str, Any] = {}
        for table, values in data.items():
            if table not in _TABLES:
                raise SceneError(table, "one of the tables " + ", ".join(_TABLES) + " (unknown table)")
            if not isinstance(values, dict):
                raise SceneError(table, "a table of keys", values)
            values = dict(values)
            allowed = [f.name for f in fields(_TABLES[table])]
            if table == "defect":
                allowed.append("sigma2")
                if "sigma2" in values:
                    clash = [k for k in ("sigma_x2", "sigma_z2", "sigma_xz") if k in values]
                    if clash:
                        raise SceneError(
                            f"defect.{clash[0]}", "absent when defect.sigma2 is given (isotropic)"
                        )
                    s2 = values.pop("sigma2")
                    values["sigma_x2"] = values["sigma_z2"] = s2
            for key in values:
                if key not in allowed:
                    raise SceneError(f"{table}.{key}", "one of the keys " + ", ".join(allowed) + " (unknown key)")
            if table == "emitter" and "half_size" in values and isinstance(values["half_size"], list):
                values["half_size"] = tuple(values["half_size"])
            parts[table] = _TABLES[table](**values)
        return cls(**parts)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Scene:
        """Read a TOML scene file (SPEC §8)."""
        path = Path(path)
        try:
            with path.open("rb") as fh:
                data = tomllib.load(fh)
        except FileNotFoundError:
            raise SceneError("scene file", "an existing TOML file", str(path)) from None
        except tomllib.TOMLDecodeError as exc:
            raise SceneError(f"scene file {path}", f"valid TOML ({exc})") from None
        return cls.from_dict(data)

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the scene as TOML, atomically."""
        import tomli_w

        from glshade.files import atomic_write_bytes

        atomic_write_bytes(Path(path), tomli_w.dumps(self.to_dict()).encode())


# --------------------------------------------------------------------------- paper
#: Stripe period the paper uses on the sphere (the others use the Emitter default, 2 mm).
PAPER_SPHERE_PERIOD_MM = 10.0


def paper_scene(
    surface: str = "flat",
    theta_deg: float = 45.0,
    sigma2: float = 4.0,
    dmax: float = 0.005,
    phase: float = 0.0,
) -> Scene:
    """The paper's geometry (Table 1, section III): camera 175.6 mm, emitter 256 mm,
    1024² pixels of 5 µm, f = 25 mm; cylinder and sphere R = 70 mm; sphere period 10 mm."""
    _choice("surface", "kind", surface, SURFACE_KINDS)
    period = PAPER_SPHERE_PERIOD_MM if surface == "sphere" else Emitter().period
    return Scene(
        camera=Camera(theta_deg=theta_deg),
        emitter=Emitter(period=period, phase=phase),
        surface=Surface(kind=surface, radius=70.0, axis="z"),
        defect=Defect.isotropic_dent(dmax=dmax, sigma2=sigma2),
    )
