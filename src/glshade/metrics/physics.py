"""Closed forms that explain the visibility numbers (derived in ``docs/physics.md``).

Small slopes, the pinhole camera, the emitter in the mirror position, the defect at the
gaze point. With ``Dc``, ``De`` the camera and emitter distances, ``δ = p / f`` the angle
one pixel row sees and ``θ`` the elevation:

- A flat mirror shows ``(Dc + De) δ`` of emitter per row. A base whose height has the
  second derivative ``κ_t`` along the plane of incidence (``-1/R`` for a convex sphere or
  a cylinder with its axis across it) scales that by ``m = 1 - 2 κ_t Dc De / ((Dc + De) sin θ)``.
- A slope ``α`` along the plane of incidence turns the reflected ray by ``2 α``:
  ``deflection_px = 2 α_max De / ((Dc + De) m δ) (1 + 2 σ_z cos θ / De)``,
  ``α_max = dmax e^(-1/2) / σ_z`` (``σ_z² = 1 / (Σ⁻¹)_zz``); the last factor is the first
  correction to the small-slope closed form (the steepest flank's distance and depth).
- The map **folds** where ``2 κ Dc De / ((Dc + De) sin θ) > 1``, ``κ`` the largest curvature
  of base plus defect along the plane of incidence: a dent's floor (``dmax / σ_z²``) or a
  bump's flanks (``2 e^(-3/2) |dmax| / σ_z²``).
- A fold caps what a viewer sees. Down the column through a dent the emitter coordinate
  in rows is ``w(ρ) = m ρ - Δ(ρ)``, ``Δ(ρ) = D t e^((1 - t²)/2)``, ``t = ρ / b``, ``D`` the
  deflection on a flat mirror and ``b = σ_z sin θ / (Dc δ)`` the dent's σ in image rows.
  Stripe pieces between the fold's two turning levels are islands, unless they reach a
  saddle of ``w``, which sits where the fold begins (columns ``±x_s``, ``x_s² = 2 σ_x² ln(F/m)``)
  at the level ``s`` by which the base's sagittal curvature bends the stripes against the
  dent's image (0 on a flat plate). A contour that reaches the cut columns therefore moves
  by at most ``Δ(t1 b) / m``, ``t1`` the root beyond 1 of ``D φ(t) - m b t = s``
  (``φ(t) = t e^((1-t²)/2)``); without a saddle offset that is ``b sqrt(2 ln(F/m))``.
- A PMD station's largest decoded shift on the screen (mm) is ``2 α_max (De + σ cos θ)``
  on a flat base, times the factor ``G`` by which a base curved along the plane of
  incidence bends it (:func:`pmd_shift_mm`, :func:`curved_base_factor`); it does not hold
  where the base's horizon falls inside the dent's window (:func:`pmd_shift_law_check`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from glshade.components.image_scale import base_curvatures, magnification
from glshade.metrics.status import WINDOW_SIGMAS
from glshade.scene import Scene

__all__ = [
    "LawCheck",
    "Laws",
    "base_curvatures",
    "curved_base_factor",
    "flat_pmd_shift_mm",
    "fold_onset_theta_deg",
    "laws",
    "pmd_shift_law_check",
    "pmd_shift_mm",
    "rig_inverse_covariance",
    "steepest_sigma_mm",
]


@dataclass(frozen=True)
class Laws:
    """The closed forms for one scene, every length in image pixels.

    ``magnification``: ``m``, the stripe scale relative to a flat mirror;
    ``fold_ratio``: ``2 κ Dc De / ((Dc + De) sin θ)``, ``κ`` the largest tangential
    curvature of base plus defect (the map folds when it exceeds 1); ``folds``;
    ``deflection_px``; ``dent_extent_px``: ``b``, the defect's σ along the image's rows;
    ``saddle_rows``: ``s``, the level of the fold's saddles above the dent's centre, in
    rows; ``visibility_px``: the contour shift a viewer sees (the fold cap where it
    applies; NaN for a folding bump, whose cap has no closed form here).
    """

    magnification: float
    fold_ratio: float
    folds: bool
    deflection_px: float
    dent_extent_px: float
    saddle_rows: float
    visibility_px: float


def rig_inverse_covariance(scene: Scene) -> tuple[float, float]:
    """``(Σ⁻¹)`` of the defect across and along the rig's plane of incidence (1/mm²):
    ``(x, z)`` at azimuth 0, turned by ``camera.azimuth_deg``."""
    a, b, c = scene.defect.inverse_covariance()
    sin_p, cos_p = math.sin(scene.gaze.azimuth_rad), math.cos(scene.gaze.azimuth_rad)
    along = a * sin_p * sin_p + 2.0 * b * sin_p * cos_p + c * cos_p * cos_p
    across = a * cos_p * cos_p - 2.0 * b * sin_p * cos_p + c * sin_p * sin_p
    return across, along


def laws(scene: Scene) -> Laws:
    """The closed forms of docs/physics.md (and the fold cap) for ``scene``."""
    cam, defect = scene.camera, scene.defect
    dc, de = scene.gaze.camera_mm, scene.gaze.screen_mm
    sin_t, cos_t = math.sin(scene.gaze.theta_rad), math.cos(scene.gaze.theta_rad)
    delta = scene.gaze.pitch_mm / cam.focal
    lever = 2.0 * dc * de / ((dc + de) * sin_t)  # mm: curvature -> fold ratio
    tangential, sagittal = base_curvatures(scene)
    m = magnification(scene)  # 1 - lever κ_t (components/image_scale.py)
    inv_xx, inv_zz = rig_inverse_covariance(scene)
    sigma_z = 1.0 / math.sqrt(inv_zz)
    b = sigma_z * sin_t / (dc * delta)
    depth = abs(defect.dmax)
    # the small-slope leading term, times the first correction: the flank of steepest slope lies
    # σ_z cos θ farther from the emitter, and its depth moves the hit point along the ray
    # by as much again (docs/physics.md)
    flat_deflection = (
        2.0
        * depth
        * math.exp(-0.5)
        / sigma_z
        * de
        / ((dc + de) * delta)
        * (1.0 + 2.0 * sigma_z * cos_t / de)
    )
    deflection = flat_deflection / m if m > 0 else math.nan
    dent_curvature = depth * inv_zz * (1.0 if defect.dmax > 0 else 2.0 * math.exp(-1.5))
    ratio = lever * (dent_curvature + tangential)
    folds = ratio > 1.0
    focus = lever * dent_curvature / m if m > 0 else math.nan  # F / m: > 1 where a dent folds
    saddle, visible = 0.0, deflection
    if defect.dmax > 0 and focus > 1.0:
        x_s2 = 2.0 / inv_xx * math.log(focus)
        saddle = abs(_saddle_rows(x_s2, sagittal, m, dc, de, sin_t, cos_t, delta))
        visible = _fold_cap(flat_deflection, b, m, saddle)
    elif folds:
        visible = math.nan
    return Laws(
        magnification=m,
        fold_ratio=ratio,
        folds=folds,
        deflection_px=deflection,
        dent_extent_px=b,
        saddle_rows=saddle,
        visibility_px=visible,
    )


def _saddle_rows(
    x_s2: float,
    sagittal: float,
    m: float,
    dc: float,
    de: float,
    sin_t: float,
    cos_t: float,
    delta: float,
) -> float:
    """How far (in rows of the emitter map) a sagittally curved base lifts the stripes
    against the dent's image at lateral offset ``x_s`` (docs/physics.md): the dent's centre
    moves ``-cos θ x² κ_s / (2 Dc δ)`` rows, the stripes
    ``cos θ x² κ_s (Dc + 2 De - 2 De Dc sin θ κ_s) / (Dc (Dc + De) δ)``."""
    scale = cos_t * x_s2 * sagittal / (dc * delta)
    return scale * ((dc + 2.0 * de - 2.0 * de * dc * sin_t * sagittal) / (dc + de) - 0.5 * m)


def _fold_cap(flat_deflection: float, b: float, m: float, saddle: float) -> float:
    """The largest shift of a contour that reaches the cut columns through a dent's fold:
    ``D φ(t1) / m`` with ``t1 >= 1`` the root of ``D φ(t) - m b t = saddle``, or the whole
    deflection when ``D - m b <= saddle`` (no island cuts it off). Bisection: the left
    side decreases from ``D - m b`` at ``t = 1`` towards ``-inf``."""

    def level(t: float) -> float:
        return flat_deflection * t * math.exp(0.5 * (1.0 - t * t)) - m * b * t

    if level(1.0) <= saddle:
        return flat_deflection / m
    lo, hi = 1.0, 2.0
    while level(hi) > saddle:
        lo, hi = hi, 2.0 * hi
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if level(mid) > saddle else (lo, mid)
    t1 = 0.5 * (lo + hi)
    return flat_deflection * t1 * math.exp(0.5 * (1.0 - t1 * t1)) / m


def fold_onset_theta_deg(scene: Scene) -> float:
    """The elevation below which ``scene``'s defect folds the stripe map (degrees; 90 when
    it folds at every elevation, 0 when at none)."""
    probe = laws(scene.updated(camera={"theta_deg": 45.0}))
    sine = probe.fold_ratio * math.sin(math.radians(45.0))  # the fold ratio is ∝ 1 / sin θ
    if sine <= 0:
        return 0.0
    return 90.0 if sine >= 1.0 else math.degrees(math.asin(sine))


def pmd_shift_mm(scene: Scene) -> float:
    """The closed form of a PMD station's largest decoded shift on the screen (mm).

    On a flat base a slope ``α`` turns the reflected ray by ``2 α``, which lands ``2 α De``
    away on the screen, the steepest flank ``σ cos θ`` farther from it:
    ``2 α_max (De + σ cos θ)`` (:func:`flat_pmd_shift_mm`). Along the plane of incidence
    a base of curvature ``κ_t`` multiplies that by :func:`curved_base_factor` (1 exactly
    where ``κ_t = 0``: the flat plate, the cylinder with its axis in the plane). Where
    both ``u`` and ``v`` are coded and the steepest flank lies across or oblique to the
    plane, the larger of its flat law and the in-plane flank's curved one. Whether the
    number holds: :func:`pmd_shift_law_check`."""
    directions = set(getattr(scene.emitter, "directions", ("v",)))
    flat = flat_pmd_shift_mm(scene)
    if "v" not in directions:
        return flat
    sigma_z = 1.0 / math.sqrt(rig_inverse_covariance(scene)[1])
    along = _flat_shift(scene, sigma_z) * curved_base_factor(scene, sigma_z)
    if sigma_z <= steepest_sigma_mm(scene) * (1.0 + 1e-9):  # the steepest flank is in-plane
        return along
    return max(flat, along)


def steepest_sigma_mm(scene: Scene) -> float:
    """The dent's σ (mm) along its steepest coded direction: the covariance's smallest
    eigenvalue where both ``u`` and ``v`` are coded, ``σ_z`` along the plane of incidence
    for ``v`` alone, ``σ_x`` across it for ``u`` alone."""
    inv_xx, inv_zz = rig_inverse_covariance(scene)
    directions = set(getattr(scene.emitter, "directions", ("v",)))
    if directions >= {"u", "v"}:
        a, b, c = scene.defect.inverse_covariance()
        largest = 0.5 * (a + c) + math.sqrt(0.25 * (a - c) ** 2 + b * b)
        return 1.0 / math.sqrt(largest)
    return 1.0 / math.sqrt(inv_zz if "v" in directions else inv_xx)


def flat_pmd_shift_mm(scene: Scene) -> float:
    """``2 α_max (De + σ cos θ)``, ``α_max = |dmax| e^(-1/2) / σ`` along the steepest coded
    direction (:func:`steepest_sigma_mm`): the shift on a flat base (mm)."""
    return _flat_shift(scene, steepest_sigma_mm(scene))


def _flat_shift(scene: Scene, sigma: float) -> float:
    slope = abs(scene.defect.dmax) * math.exp(-0.5) / sigma
    de = scene.gaze.screen_mm
    return 2.0 * slope * (de + sigma * math.cos(scene.gaze.theta_rad))


def curved_base_factor(scene: Scene, sigma: float) -> float:
    """``G``: how much a base of curvature ``κ_t`` along the plane of incidence scales the
    flat law of a flank ``σ`` mm from the dent's centre (docs/physics.md, "The PMD
    shift on a curved base"). The ray meets the dent ``|D| / tan e`` farther along than
    the base, where the base's normal is turned by ``κ_t |D| / tan e`` (``e`` the flank's
    local elevation): the reflected ray turns by twice that beside the slope's ``2 α``.
    With ``c = s κ_t / tan e_s`` on the flank ``s`` (−1 towards the camera, +1 towards the
    screen) the shift ``∝ exp(-w²/2) (w / σ + c)`` peaks at ``w² + c σ w = 1``, and the
    flank's reflected ray meets the screen ``ψ = 2 κ_t σ`` off its normal, which stretches
    the shift by ``1 / cos² ψ``:

        G = max_s  (L_s / L_-) e^((1 - w²)/2) (w + c σ) / cos² ψ,
        L_s = De - s σ cos θ,   e_s = θ - s σ sin θ / Dc + s κ_t σ.

    1 exactly for ``κ_t = 0``; NaN where neither flank is seen above its horizon."""
    tangential = base_curvatures(scene)[0]
    theta = scene.gaze.theta_rad
    dc, de = scene.gaze.camera_mm, scene.gaze.screen_mm
    far = de + sigma * math.cos(theta)
    stretch = math.cos(2.0 * tangential * sigma) ** 2
    best = -math.inf
    for side in (-1.0, 1.0):
        elevation = theta - side * sigma * math.sin(theta) / dc + side * tangential * sigma
        if not 0.0 < elevation < math.pi:
            continue
        c_sigma = side * tangential * sigma / math.tan(elevation)
        w = 0.5 * (math.sqrt(c_sigma * c_sigma + 4.0) - c_sigma)
        lever = (de - side * sigma * math.cos(theta)) / far
        factor = lever * math.exp(0.5 * (1.0 - w * w)) * (w + c_sigma) / stretch
        best = max(best, factor)
    return best if best > -math.inf else math.nan


@dataclass(frozen=True)
class LawCheck:
    """Whether a closed form holds for a scene: ``status`` ``ok`` or why not
    (``grazing``), and ``reason`` (empty when ok)."""

    status: str = "ok"
    reason: str = ""


def pmd_shift_law_check(scene: Scene) -> LawCheck:
    """Whether :func:`pmd_shift_mm` can be read for ``scene``: ``grazing`` where the local
    elevation of the base falls to 0 within the dent's window along the plane of
    incidence (±``WINDOW_SIGMAS`` σ_z; ``e(z) = θ + z (κ_t - sin θ / Dc)``). There the
    pixels near the base's horizon see the screen through grazing rays, whose screen
    points the dent's faint tail swings by more than its flank's slope does, and the
    largest shift need not be the flank's the law describes (docs/physics.md)."""
    sigma_z = 1.0 / math.sqrt(rig_inverse_covariance(scene)[1])
    theta = scene.gaze.theta_rad
    turn = base_curvatures(scene)[0] - math.sin(theta) / scene.gaze.camera_mm
    reach = WINDOW_SIGMAS * sigma_z
    lowest = theta - reach * abs(turn)
    if lowest > 0.0:
        return LawCheck()
    side = "far" if turn < 0.0 else "near"
    return LawCheck(
        "grazing",
        f"the base's local elevation falls to {math.degrees(lowest):.1f}° within the dent's "
        f"±{WINDOW_SIGMAS:g} σ ({reach:.3g} mm) along the plane of incidence, on its {side} "
        "side: pixels there see the screen through grazing rays, the dent's tail may move "
        "their screen points more than its flank does, and the closed form describes only "
        "the flank (a higher θ keeps the horizon out of the dent's window)",
    )
