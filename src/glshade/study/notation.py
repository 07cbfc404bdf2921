"""The study report's symbols (each defined once, with its unit and its value in the run)
and its laws (each stated once, in one section, and named elsewhere). The closed forms
are derived in ``docs/physics.md`` and computed by :mod:`glshade.metrics.physics`."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from glshade.study.plan import surface_label
from glshade.study.shapes import Shape, shape

if TYPE_CHECKING:
    from glshade.scene import Scene

#: The laws as the report names them, and their statements.
LAWS = (
    (
        "magnification law",
        "a base curved along the plane of incidence scales the stripes by "
        "m = 1 - 2 κ_t Dc De / ((Dc + De) sin θ): m > 1 on a convex base (κ_t < 0; "
        "m = 1 + 2 Dc De / (R sin θ (Dc + De)) for a radius R), m < 1 on a concave one, m = 1 "
        "where the base is flat along the plane. Every shift in pixels is divided by m.",
    ),
    (
        "deflection law",
        "the dent moves the rays by D / m pixels, D = 2 (dmax/σ) e^(-1/2) De f / ((Dc + De) p) "
        "· (1 + 2 σ cos θ / De). With m = 1 it depends on θ only through the last factor (the "
        "steepest flank lies σ cos θ farther from the emitter): a few per cent at low θ.",
    ),
    (
        "fold law",
        "the stripe map folds (the dent's floor focuses the rays before they reach the "
        "emitter) where the fold ratio 2 κ Dc De / ((Dc + De) sin θ) exceeds 1, "
        "κ = κ_t + dmax/σ²: a dent folds below the θ where that ratio is 1 (its fold onset).",
    ),
    (
        "fold cap law",
        "where the map folds, only the contours outside the band in which the rays move "
        "more than their distance from the dent reach the cut columns: the visible shift is "
        "capped at b sqrt(2 ln(F/m)), and b shrinks with sin θ as the view grazes.",
    ),
    (
        "saddle law",
        "a base curved across the plane of incidence (κ_s ≠ 0) lifts the fold's saddles and "
        "with them the fold cap: a dent that folds keeps more of its shift at low views.",
    ),
)


def laws_section() -> list[str]:
    """The report's Laws section: every closed form once, by name."""
    return [
        "## Laws",
        "",
        "The closed forms behind the numbers (derived in `docs/physics.md`: small slopes, a "
        "pinhole camera, the dent at the gaze point). The rest of this report names them.",
        "",
        *[f"- **{name.capitalize()}**: {text}" for name, text in LAWS],
        "",
    ]


def _numbers(values, fmt: str = "{:g}") -> str:
    return ", ".join(fmt.format(v) for v in values)


def _span(values: Sequence[float | None], fmt: str = "{:.3g}") -> str:
    finite = [v for v in values if v is not None and math.isfinite(v)]
    if not finite:
        return "—"
    lo, hi = min(finite), max(finite)
    return (
        fmt.format(lo)
        if fmt.format(lo) == fmt.format(hi)
        else f"{fmt.format(lo)} to {fmt.format(hi)}"
    )


def _per_surface(plan, value: Callable[[str], str]) -> str:
    """One value, or the value of each surface when they differ."""
    found = {surface_label(s): value(s) for s in plan.surfaces}
    if len(set(found.values())) == 1:
        return next(iter(found.values()))
    return "; ".join(f"{label} {v}" for label, v in found.items())


def image_size(plan) -> tuple[int, int]:
    """``(width, height)`` in pixels of the run's images."""
    camera = plan.scene(plan.surfaces[0], plan.thetas[0], plan.sigma2s[0], plan.dmaxs[0]).camera
    return int(camera.width), int(camera.height)


#: A row of the symbol table: ``(symbol, meaning, unit, value in this study)``.
SymbolRow = tuple[str, str, str, str]


@dataclass(frozen=True)
class _Study:
    """What the symbol table's values are computed from: the measured rows, the plan, each
    surface's scene at the plan's first case, the image size, the measured base shapes and
    sin θ and σ over the plan."""

    rows: Sequence[Mapping]
    plan: Any
    scenes: dict[str, Scene]
    width: int
    height: int
    shapes: dict[str, Shape]
    sin: list[float]
    sigmas: list[float]

    @classmethod
    def of(cls, rows: Sequence[Mapping], plan) -> _Study:
        """The study of ``rows`` measured with ``plan``."""
        scenes = {
            s: plan.scene(s, plan.thetas[0], plan.sigma2s[0], plan.dmaxs[0]) for s in plan.surfaces
        }
        width, height = image_size(plan)
        measured_surfaces = list(dict.fromkeys(r["surface"] for r in rows))
        shapes = {s: shape(rows, s) for s in measured_surfaces}
        sin = [math.sin(math.radians(t)) for t in plan.thetas]
        sigmas = [math.sqrt(v) for v in plan.sigma2s]
        return cls(rows, plan, scenes, width, height, shapes, sin, sigmas)

    def per_surface(self, value: Callable[[str], str]) -> str:
        """:func:`_per_surface` over this study's plan."""
        return _per_surface(self.plan, value)

    def column(self, name: str, fmt: str = "{:.3g}") -> str:
        """The span of a results column, per surface; ``—`` without rows."""

        def one(surface: str) -> str:
            return _span([r.get(name) for r in self.rows if r["surface"] == surface], fmt)

        return self.per_surface(one) if self.rows else "—"

    def scene_value(self, get: Callable, fmt: str = "{:g}") -> str:
        """A value of each surface's scene, formatted, per surface."""
        return self.per_surface(lambda s: fmt.format(get(self.scenes[s])))

    def dent_curvatures(self) -> list[float]:
        """dmax/σ² of every dent of the plan."""
        return [d / v for d in self.plan.dmaxs for v in self.plan.sigma2s]

    def lever(self, surface: str, sine: float) -> float:
        """2 Dc De / ((Dc + De) sin θ) of a surface's scene."""
        scene = self.scenes[surface]
        dc, de = scene.camera.distance, scene.emitter.distance
        return 2 * dc * de / ((dc + de) * sine)


def _radius(study: _Study, surface: str) -> str:
    """The radii of a surface's base along and across the plane of incidence."""
    sh = study.shapes.get(surface)
    if sh is None:
        return "—"
    parts = [
        f"{1 / abs(k):.3g} {where}"
        for k, where in ((sh.kappa_t, "along"), (sh.kappa_s, "across"))
        if abs(k) > 1e-9
    ]
    return ", ".join(parts) if parts else "— (not curved)"


def _curvature(study: _Study, index: int) -> Callable[[str], str]:
    """A surface's base curvature along (``index`` 0) or across (1) the plane of incidence."""

    def one(surface: str) -> str:
        sh = study.shapes.get(surface)
        if sh is None:
            return "—"
        value = (sh.kappa_t, sh.kappa_s)[index]
        return "0" if abs(value) < 1e-9 else f"{value:+.3g}"

    return one


def _kappa_range(study: _Study, surface: str) -> str:
    """The span of κ_t + dmax/σ² over the plan's dents on one surface."""
    sh = study.shapes.get(surface)
    base = sh.kappa_t if sh is not None else 0.0
    curv = study.dent_curvatures()
    return _span([base + min(curv), base + max(curv)], "{:.3g}")


def _b_range(study: _Study, surface: str) -> str:
    """The span of the dent's σ in image rows, σ sin θ f / (Dc p), over the plan."""
    cam = study.scenes[surface].camera
    scale = cam.focal / (cam.distance * cam.pixel_pitch)
    sin, sigmas = study.sin, study.sigmas
    return _span([min(sigmas) * min(sin) * scale, max(sigmas) * max(sin) * scale])


def _f_range(study: _Study, surface: str) -> str:
    """The span of the focusing strength F over the plan on one surface."""
    curv = study.dent_curvatures()
    sin = study.sin
    return _span(
        [study.lever(surface, max(sin)) * min(curv), study.lever(surface, min(sin)) * max(curv)]
    )


def _flat_deflection(study: _Study, surface: str) -> str:
    """The span of the deflection law's D before the magnification, on one surface."""
    values = []
    for r in study.rows:
        law, m = r.get("deflection_law_px"), r.get("magnification")
        if r["surface"] == surface and law is not None and math.isfinite(law):
            values.append(law * (m if m is not None and math.isfinite(m) else 1.0))
    return _span(values)


def _plan_symbols(study: _Study) -> list[SymbolRow]:
    """The symbols of the plan's axes: θ, σ², σ and dmax."""
    plan = study.plan
    return [
        ("θ", "camera elevation above the surface at the gaze point (90° looks straight down)",
         "deg", _numbers(plan.thetas)),
        ("σ²", "variance of the Gaussian dent (isotropic)", "mm²", _numbers(plan.sigma2s)),
        ("σ", "width of the dent, sqrt(σ²)", "mm", _numbers(study.sigmas, "{:.3g}")),
        ("dmax", "depth of the dent", "µm", _numbers(d * 1000 for d in plan.dmaxs)),
    ]  # fmt: skip


def _setup_symbols(study: _Study) -> list[SymbolRow]:
    """The symbols of the camera and the emitter: Dc, De, f, p and the stripe period."""
    value = study.scene_value
    return [
        ("Dc", "distance from the camera to the gaze point", "mm",
         value(lambda sc: sc.camera.distance)),
        ("De", "distance from the emitter (the stripe screen) to the gaze point", "mm",
         value(lambda sc: sc.emitter.distance)),
        ("f", "focal length of the camera", "mm", value(lambda sc: sc.camera.focal)),
        ("p", f"pixel pitch of the {study.width}×{study.height} image", "µm",
         value(lambda sc: sc.camera.pixel_pitch * 1000)),
        ("period", "stripe period on the emitter", "mm", value(lambda sc: sc.emitter.period)),
    ]  # fmt: skip


def _curvature_symbols(study: _Study) -> list[SymbolRow]:
    """The symbols of the base's and the dent's curvature: κ_t, κ_s, R and κ."""
    per_surface = study.per_surface
    return [
        ("κ_t", "curvature (second derivative of the height) of the base along the plane of "
         "incidence, at the gaze point; negative is convex", "1/mm",
         per_surface(_curvature(study, 0))),
        ("κ_s", "the same across the plane of incidence", "1/mm",
         per_surface(_curvature(study, 1))),
        ("R", "radius of a curved base, 1/|κ_t| or 1/|κ_s|", "mm",
         per_surface(lambda s: _radius(study, s))),
        ("κ", "largest curvature along the plane of incidence of base plus dent, κ_t + dmax/σ² "
         "(the dent's floor)", "1/mm", per_surface(lambda s: _kappa_range(study, s))),
    ]  # fmt: skip


def _law_symbols(study: _Study) -> list[SymbolRow]:
    """The symbols of the laws: m, the fold ratio, D, b and F."""
    per_surface = study.per_surface
    return [
        ("m", "magnification of the stripes by the base (magnification law; `magnification`)",
         "—", study.column("magnification")),
        ("fold ratio", "2 κ Dc De / ((Dc + De) sin θ); the stripe map folds above 1 (fold law; "
         "`fold_ratio`)", "—", study.column("fold_ratio")),
        ("D", "deflection on a flat mirror: how far the dent moves the rays before the "
         "magnification (deflection law)", "px",
         per_surface(lambda s: _flat_deflection(study, s))),
        ("b", "the dent's σ in image rows, σ sin θ f / (Dc p)", "px",
         per_surface(lambda s: _b_range(study, s))),
        ("F", "how strongly the dent's floor focuses the rays, D √e / b = 2 Dc De dmax / "
         "((Dc + De) σ² sin θ); the fold caps the shift where F/m > √e (fold cap law)", "—",
         per_surface(lambda s: _f_range(study, s))),
    ]  # fmt: skip


def _constant_symbols(study: _Study) -> list[SymbolRow]:
    """The symbols that do not depend on the cases: e, ρ and px."""
    width, height = study.width, study.height
    return [
        ("e", "Euler's number", "—", "2.718"),
        ("ρ", "Spearman rank correlation (of θ or σ² with the visibility)", "—", "-1 to +1"),
        ("px", f"one pixel of the {width}×{height} image", "—", f"{width}×{height} px"),
    ]


def symbol_rows(rows: Sequence[Mapping], plan) -> list[SymbolRow]:
    """``(symbol, meaning, unit, value in this study)`` for every symbol the report uses."""
    study = _Study.of(rows, plan)
    return [
        *_plan_symbols(study),
        *_setup_symbols(study),
        *_curvature_symbols(study),
        *_law_symbols(study),
        *_constant_symbols(study),
    ]


def symbols_section(rows: Sequence[Mapping], plan) -> list[str]:
    """The report's symbol table."""
    lines = [
        "## Symbols",
        "",
        "Every symbol of this report, its unit and its value in this study (a range over the "
        "study's cases, or per surface where the surfaces differ):",
        "",
        "| symbol | meaning | unit | value here |",
        "|---|---|---|---|",
    ]
    lines += [
        f"| {s} | {meaning} | {unit} | {value} |"
        for s, meaning, unit, value in symbol_rows(rows, plan)
    ]
    return lines + [""]
