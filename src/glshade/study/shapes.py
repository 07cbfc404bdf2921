"""What a study's surface is, as its report describes it: convex, concave or flat along the
plane of incidence (from the rows' ``magnification``, the magnification law's value), its
curvatures at the gaze point (asked of its surface component), and whether it is a
free-form surface (a formula or a height map, whose curvature holds at the gaze point
only). Never from the surface's name."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

from glshade.metrics import physics
from glshade.study.plan import case_scene, surface_label

#: |m - 1| below this is "flat along the plane of incidence".
FLAT_M = 0.01

CONVEX, CONCAVE, FLAT = "convex", "concave", "flat"


@dataclass(frozen=True)
class Shape:
    """One surface of a study: its label, its description, ``kind`` (convex, concave
    or flat along the plane of incidence), ``m`` at the highest and the lowest θ of its
    rows, its tangential and sagittal curvatures at the gaze point (1/mm, convex
    negative) and ``free_form``."""

    surface: str
    label: str
    description: str
    kind: str
    theta_high: float
    theta_low: float
    m_high: float
    m_low: float
    kappa_t: float
    kappa_s: float
    free_form: bool

    @property
    def magnifies(self) -> bool:
        return self.kind == CONVEX

    @property
    def curved_across(self) -> bool:
        return abs(self.kappa_s) > 1e-9


def _free_form(scene) -> bool:
    """A base without closed-form curvature everywhere: not a plane and not a quadric."""
    from glshade.components.surface.flat import Flat
    from glshade.components.surface.quadric import Quadric

    return not isinstance(scene.active.surface, Flat | Quadric)


def _magnification(rows: Sequence[Mapping], surface: str, theta: float) -> float:
    """The magnification law's value at θ: the rows' column, or the law itself when the
    rows do not carry it."""
    for r in rows:
        if r["surface"] == surface and r["theta_deg"] == theta:
            value = r.get("magnification")
            if value is not None and math.isfinite(float(value)):
                return float(value)
    return physics.laws(case_scene(surface, theta)).magnification


def shape(rows: Sequence[Mapping], surface: str) -> Shape:
    """The :class:`Shape` of one surface of ``rows``."""
    thetas = sorted({r["theta_deg"] for r in rows if r["surface"] == surface})
    high, low = thetas[-1], thetas[0]
    m_high, m_low = _magnification(rows, surface, high), _magnification(rows, surface, low)
    extreme = max((m_high, m_low), key=lambda m: abs(m - 1.0))
    kind = FLAT if abs(extreme - 1.0) < FLAT_M else CONVEX if extreme > 1.0 else CONCAVE
    scene = case_scene(surface)
    kappa_t, kappa_s = physics.base_curvatures(scene)
    return Shape(
        surface=surface,
        label=surface_label(surface),
        description=scene.active.surface.describe(scene),
        kind=kind,
        theta_high=high,
        theta_low=low,
        m_high=m_high,
        m_low=m_low,
        kappa_t=kappa_t,
        kappa_s=kappa_s,
        free_form=_free_form(scene),
    )


def curvature_text(kappa: float) -> str:
    """A curvature as the report writes it: ``-0.0143 /mm (R 70 mm, convex)``."""
    if abs(kappa) < 1e-9:
        return "0 /mm"
    return f"{kappa:+.3g} /mm (R {1.0 / abs(kappa):.3g} mm, {'convex' if kappa < 0 else 'concave'})"
