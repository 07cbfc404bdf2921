"""How much emitter one image row sees: the closed form behind the stripes' resolution.

A flat mirror shows ``(Dc + De) δ`` mm of emitter per image row (``Dc``, ``De`` the camera
and emitter distances, ``δ = pitch / focal`` the angle of one row). A base whose height has
the second derivative ``κ_t`` along the plane of incidence scales that by the
magnification ``m = 1 - 2 κ_t Dc De / ((Dc + De) sin θ)`` (convex: ``κ_t < 0``, ``m > 1``;
docs/physics.md). A stripe period ``P`` therefore spans ``P / ((Dc + De) δ m)`` rows at
the gaze point, and the metric resolves it where that is at least its ``min_period_px``.

These forms take a scene (duck-typed: its camera and emitter tables and its surface
component's ``second_derivatives``); the emitter's ``period = "auto"`` and the metric's
``unresolved`` status both read them.
"""

from __future__ import annotations

import math
from typing import Any

#: Pixels per stripe period below which the metric leaves a pixel out (its default
#: ``min_period_px``).
MIN_PERIOD_PX = 4.0
#: Pixels per period that ``emitter.period = "auto"`` aims for at the gaze point: half as
#: much again as the least the metric resolves, so the dent's neighbourhood resolves too.
AUTO_PERIOD_PX = 6.0
#: ``auto`` periods are whole multiples of this (mm): the metric's default phase step.
AUTO_PERIOD_STEP_MM = 0.25


def base_curvatures(scene: Any) -> tuple[float, float]:
    """Second derivatives of the base height at the gaze point (1/mm): along the plane of
    incidence (tangential, ``z`` at azimuth 0) and across it (sagittal, ``x``). Convex is
    negative: a sphere has ``(-1/R, -1/R)``, a cylinder with axis z ``(0, -1/R)``, with
    axis x ``(-1/R, 0)``; R < 0 (concave) flips the signs. A turned rig
    (``camera.azimuth_deg`` φ) sees ``f_zz cos² φ + f_xx sin² φ`` along its plane (the
    surfaces' mixed derivative at the gaze point is 0 for the analytic kinds; a free-form
    surface's is neglected here)."""
    f_zz, f_xx = scene.active.surface.second_derivatives(scene)
    c2, s2 = math.cos(scene.gaze.azimuth_rad) ** 2, math.sin(scene.gaze.azimuth_rad) ** 2
    return f_zz * c2 + f_xx * s2, f_xx * c2 + f_zz * s2


def magnification(scene: Any) -> float:
    """``m``: the stripe scale at the gaze point relative to a flat mirror (1 on the flat
    plate; <= 0 where a concave base focuses the emitter: no finite scale)."""
    dc, de = scene.gaze.camera_mm, scene.gaze.screen_mm
    lever = 2.0 * dc * de / ((dc + de) * math.sin(scene.gaze.theta_rad))
    return 1.0 - lever * base_curvatures(scene)[0]


def emitter_mm_per_row(scene: Any) -> float:
    """Emitter length (mm along ``v``) one image row sees at the gaze point; NaN where
    the magnification has no finite value."""
    cam = scene.camera
    m = magnification(scene)
    if not m > 0.0:
        return math.nan
    return (scene.gaze.camera_mm + scene.gaze.screen_mm) * scene.gaze.pitch_mm / cam.focal * m


def period_px(scene: Any, period_mm: float) -> float:
    """Image rows one stripe period spans at the gaze point (NaN: no closed form)."""
    return period_mm / emitter_mm_per_row(scene)


def smallest_resolved_period_mm(scene: Any, min_period_px: float = MIN_PERIOD_PX) -> float:
    """The shortest stripe period that spans ``min_period_px`` rows at the gaze point."""
    return min_period_px * emitter_mm_per_row(scene)


def auto_period_mm(scene: Any) -> float:
    """The period ``emitter.period = "auto"`` picks: the shortest multiple of
    :data:`AUTO_PERIOD_STEP_MM` that spans :data:`AUTO_PERIOD_PX` rows at the gaze point
    (at least one step; where the closed form has no value, a concave base focusing the
    emitter, the emitter's default 2 mm)."""
    needed = smallest_resolved_period_mm(scene, AUTO_PERIOD_PX)
    if not math.isfinite(needed):
        return 2.0
    steps = max(1, math.ceil(needed / AUTO_PERIOD_STEP_MM - 1e-9))
    return steps * AUTO_PERIOD_STEP_MM
