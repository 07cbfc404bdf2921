"""First-order sensitivities of a flat mirror's measured slopes to what the station
believes of its geometry (docs/budget.md, "Closed forms"), the budget's checks.

The station (:mod:`glshade.instruments.pmd.reconstruct`) takes pixel ``p``'s point where
its *believed* chief ray meets the nominal surface, ``P' = C' + t' d'``, and its normal as
the bisector of the directions from ``P'`` to the believed principal point ``C'`` and to
the believed screen point ``S'`` of the coordinates ``(u, v)`` it decoded (which are the
truth's: the frames come from the truth). On a flat mirror ``y = 0`` of true normal
``ŷ``, a small change of belief moves them by ``ΔC``, ``Δd`` (the ray) and ``ΔS``; to
first order

- ``ΔP = Π(ΔC + t Δd)``, ``Π v = v - (v_y / d_y) d`` (the point stays on the plane,
  moving along the ray), ``t = |P - C|``;
- ``Δc = (I - c cᵀ)(ΔC - ΔP) / t`` and ``Δr = (I - r rᵀ)(ΔS - ΔP) / L`` for the unit
  directions ``c`` to the camera and ``r`` to the screen, ``L = |S - P|``;
- ``Δn = (I - ŷŷᵀ)(Δc + Δr) / |c + r|``, ``|c + r| = 2 cos i``: the slope error
  ``(Δ∂d/∂x, Δ∂d/∂z) = (-Δn_x, -Δn_z)``, and the dent, seen at ``P'``, shifts by ``ΔP``.

A component of ``Δc + Δr`` in the plane of incidence is halved; one across it is divided
by ``2 cos i``. A screen moved by ``δ_D`` along its normal (``ΔS = -δ_D n_E``, ``ΔC = Δd
= 0``) gives ``|Δr| = δ_D sin α / L`` (α between the reflected ray and the screen's
normal), so a slope error of ``δ_D sin α / (2 L)`` in the plane of incidence; a camera
translated by ``δ_C`` with its orientation kept (``Δd = 0``) moves ``P`` by ``Π δ_C`` and
leaves ``c`` as it was (``ΔC - ΔP`` is along ``c``), so ``|Δr| = δ_⊥ / L``, ``δ_⊥`` the
component of ``Π δ_C`` across ``r``. The changes ``ΔC``, ``Δd`` and ``ΔS`` of a parameter
are read from the scene's own geometry (its camera's chief rays, its screen's plane) by a
central difference; the propagation above is the closed form.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from glshade.scene import Scene

#: The camera's and the screen's keys whose belief the closed form follows: each moves
#: the believed chief rays or the believed screen plane, and nothing else the station uses.
CAMERA_KEYS = frozenset(
    {
        "position", "tvec", "rvec", "distance", "theta_deg", "azimuth_deg", "yaw_deg",
        "pitch_deg", "roll_deg", "look_at", "up", "focal", "pixel_pitch", "intrinsics",
        "distortion",
    }
)  # fmt: skip
SCREEN_KEYS = frozenset(
    {"distance", "centre", "look_at", "up", "yaw_deg", "pitch_deg", "roll_deg", "sag"}
)
#: The central difference's step, as a share of the input's σ.
STEP_SHARE = 1e-3


def is_flat(scene: Scene) -> bool:
    """The part is a plane ``y = 0``: its surface's height is 0 over a grid of ±100 mm."""
    x, z = np.meshgrid(np.linspace(-100.0, 100.0, 9), np.linspace(-100.0, 100.0, 9))
    height = np.asarray(scene.active.surface.height(scene, x, z), np.float64)
    return bool(np.all(height == 0.0))


def has_closed_form(scene: Scene, path: str) -> bool:
    """Whether :func:`flat_sensitivity` follows a belief of ``path`` on ``scene``: a flat
    part and a parameter of the camera's pose or intrinsics or of the screen's pose."""
    if not is_flat(scene):
        return False
    table, _, key = path.partition("[")[0].partition(".")
    return (table == "camera" and key in CAMERA_KEYS) or (table == "emitter" and key in SCREEN_KEYS)


@dataclass(frozen=True)
class FlatGeometry:
    """A flat mirror's station, per pixel (part frame, mm): the principal point ``C``, the
    unit chief rays ``d`` (H, W, 3), where they meet ``y = 0`` (``P``, ``t`` the distance),
    the reflected unit rays ``r``, the distance ``L`` to the screen along them, the screen
    points ``S`` and their coordinates ``uv``; ``valid`` where the ray meets the mirror in
    front and then the screen's rectangle from the front."""

    C: np.ndarray
    d: np.ndarray
    t: np.ndarray
    P: np.ndarray
    r: np.ndarray
    L: np.ndarray
    S: np.ndarray
    uv: np.ndarray
    valid: np.ndarray


def flat_geometry(scene: Scene) -> FlatGeometry:
    """The chief rays of ``scene``'s pinhole camera on a mirror ``y = 0``, reflected to its
    screen's plane (the float64 geometry; no rendering)."""
    pose = scene.camera_pose()
    C, d = scene.camera.pixel_rays(pose=pose)
    C = np.asarray(C, np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -C[1] / d[..., 1]
    P = C + t[..., None] * d
    r = d * np.array([1.0, -1.0, 1.0])
    plane = scene.emitter_plane()
    facing = r @ plane.normal
    with np.errstate(divide="ignore", invalid="ignore"):
        L = (-plane.distance - P @ plane.normal) / facing
    S = P + L[..., None] * r
    rel = S - plane.centre
    uv = np.stack([rel @ plane.e_u, rel @ plane.e_v], axis=-1)
    hu, hv = scene.emitter.half_size
    valid = (t > 0.0) & (facing < 0.0) & (L > 0.0)
    valid &= (np.abs(uv[..., 0]) <= hu) & (np.abs(uv[..., 1]) <= hv)
    return FlatGeometry(C, d, t, P, r, L, S, uv, valid)


@dataclass(frozen=True)
class FlatSensitivity:
    """The first-order error of a belief of ``path`` per unit of it, per pixel: the slope
    map's ``slopes_urad`` (H, W, 2: µrad per unit of ``Δ∂d/∂x``, ``Δ∂d/∂z``) and the
    believed point's ``shift_mm`` (H, W, 2: its ``x`` and ``z``, mm per unit), over the
    ``valid`` pixels (:class:`FlatGeometry`)."""

    path: str
    slopes_urad: np.ndarray
    shift_mm: np.ndarray
    valid: np.ndarray

    def slope_rms_urad(self, pixels: np.ndarray | None = None) -> float:
        """The root mean square of the slope error's magnitude over the valid pixels (and
        ``pixels``, where given), µrad per unit."""
        where = self.valid if pixels is None else self.valid & pixels
        magnitude = np.hypot(self.slopes_urad[..., 0], self.slopes_urad[..., 1])[where]
        return math.sqrt(float(np.mean(magnitude**2))) if magnitude.size else math.nan

    def slope_rms_tilt_removed_urad(self, pixels: np.ndarray | None = None) -> float:
        """The same of the slope error less its uniform tilt (each component's mean over
        those pixels), µrad per unit: what remains of a belief's first-order error once a
        reference flat (or the part's believed orientation) takes the tilt out. Linear in
        the belief, like the slope rms (:func:`glshade.uncertainty.draws.tilt_removed_rms`,
        what a draw measures)."""
        from glshade.uncertainty.draws import tilt_removed_rms

        where = self.valid if pixels is None else self.valid & pixels
        found = tilt_removed_rms(self.slopes_urad[where])
        return math.nan if found is None else found

    def at(self, row: float, col: float) -> tuple[float, float]:
        """The slope error's magnitude (µrad per unit) and the point's shift (mm per unit)
        at the fractional pixel ``(row, col)`` (bilinear)."""
        from glshade.instruments.pmd.reconstruct import sample

        rows, cols = np.array([row]), np.array([col])

        def at(image: np.ndarray) -> float:
            return float(sample(np.where(self.valid, image, np.nan), rows, cols)[0])

        slope = math.hypot(at(self.slopes_urad[..., 0]), at(self.slopes_urad[..., 1]))
        return slope, math.hypot(at(self.shift_mm[..., 0]), at(self.shift_mm[..., 1]))


def flat_sensitivity(scene: Scene, path: str, step: float) -> FlatSensitivity:
    """The closed form (module doc) of a belief of ``path`` on ``scene``'s flat mirror,
    ``ΔC``, ``Δd`` and ``ΔS`` taken from the scene's geometry at ``value ± step``."""
    truth = flat_geometry(scene)
    value = float(scene.value(path))
    ahead = _believed(scene, path, value + step, truth)
    behind = _believed(scene, path, value - step, truth)
    dC, dd, dS = ((a - b) / (2.0 * step) for a, b in zip(ahead, behind, strict=True))
    d, t, r, L = truth.d, truth.t, truth.r, truth.L
    dP = dC + t[..., None] * dd
    dP = dP - (dP[..., 1] / d[..., 1])[..., None] * d
    c = -d
    dc = _across(c, dC - dP) / t[..., None]
    dr = _across(r, dS - dP) / L[..., None]
    bisector = -2.0 * d[..., 1]  # |c + r| = 2 cos i
    dn = (dc + dr) / bisector[..., None]
    slopes = 1e6 * np.stack([-dn[..., 0], -dn[..., 2]], axis=-1)
    shift = np.stack([dP[..., 0], dP[..., 2]], axis=-1)
    return FlatSensitivity(path, slopes, shift, truth.valid)


def _believed(
    scene: Scene, path: str, value: float, truth: FlatGeometry
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The believed principal point, chief rays and screen points of ``truth``'s
    coordinates, where ``path`` is believed to be ``value``."""
    believed = scene.with_value(path, value)
    pose = believed.camera_pose()
    C, d = believed.camera.pixel_rays(pose=pose)
    plane = believed.emitter_plane()
    uv = truth.uv
    S = plane.centre + uv[..., :1] * plane.e_u + uv[..., 1:] * plane.e_v
    sag = tuple(float(c) for c in getattr(believed.emitter, "sag", ()) or ())
    if any(sag):  # the emitting layer sags along the normal: w = a s² + b t² + c s t
        hu, hv = believed.emitter.half_size
        s, v = uv[..., 0] / hu, uv[..., 1] / hv
        w = sag[0] * s * s + sag[1] * v * v + sag[2] * s * v
        S = S + w[..., None] * plane.normal
    return np.broadcast_to(np.asarray(C, np.float64), S.shape), np.asarray(d), S


def _across(unit: np.ndarray, vector: np.ndarray) -> np.ndarray:
    """``(I - u uᵀ) v`` per pixel."""
    return vector - np.sum(unit * vector, axis=-1, keepdims=True) * unit


# --------------------------------------------------------------------------- checks
