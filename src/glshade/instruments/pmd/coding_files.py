"""What ``glshade coding`` writes (docs/coding.md): the report's numbers as JSON
(:func:`summary`), the scene with the recommended coding (:func:`coded_scene`) and the
plot of modulation against period (:func:`write_plot`, atomically)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from glshade.errors import GlshadeError
from glshade.instruments.pmd.coding import CodingPlan, CodingReport
from glshade.metrics.coding_laws import box_share, closed_form_share
from glshade.scene import Scene


# --------------------------------------------------------------------------- JSON
def _number(value: float) -> float | None:
    """A JSON number (None where not finite)."""
    return round(float(value), 6) if math.isfinite(value) else None


def _plan(plan: CodingPlan) -> dict[str, Any]:
    return {
        "periods_mm": [_number(p) for p in plan.periods_mm],
        "shifts": plan.shifts,
        "ratios": [_number(r) for r in plan.ratios],
        "noise_mm": _number(plan.noise_mm),
        "margin_sigmas": _number(plan.margin_sigmas),
        "finest_share": _number(plan.share),
        "quantisation_mm": _number(plan.quantisation_mm),
        "quantisation_bound_mm": _number(plan.quantisation_bound_mm),
        "gamma_mm": _number(plan.gamma_mm),
        "frames": plan.frames,
        "memory_mib": plan.budget_mib if plan.memory_bytes else None,
        "status": plan.status,
        "status_reason": plan.reason,
    }


def summary(report: CodingReport) -> dict[str, Any]:
    """The report's numbers as one JSON-ready dict (NaN as None)."""
    probe, cam = report.probe, report.scene.camera
    rec, rng = report.recommended, report.ranges
    de = report.scene.gaze.screen_mm
    return {
        "scene": report.scene.title(),
        "size": [cam.width, cam.height],
        "supersample": report.scene.render.supersample,
        "directions": list(probe.directions),
        "sensor": report.sensor,
        "target_noise_mm": report.settings.target_noise_mm,
        "resolved_share": report.settings.resolved_share,
        "margin_sigmas": report.settings.margin_sigmas,
        "memory_budget_mib": round(report.budget_bytes / (1 << 20), 3),
        "modulation": {
            "periods_mm": [_number(p) for p in probe.periods_mm],
            "pixels": probe.pixels,
            "in_window": probe.in_window,
            **{
                d: {
                    "rendered": [_number(s) for s in probe.share[i]],
                    "closed_form": [_number(s) for s in report.closed_form[i]],
                    "pixel_box": [_number(s) for s in report.pixel_box[i]],
                    "footprint_mm": _number(report.footprint_mm[d]),
                    "blur_mm": _number(report.blur_mm[d]),
                    "finest_resolved_mm": _number(report.resolved_each[d].period_mm),
                }
                for i, d in enumerate(probe.directions)
            },
        },
        "finest_resolved_mm": _number(report.resolved.period_mm),
        "finest_resolved_status": report.resolved.status,
        "finest_resolved_reason": report.resolved.reason,
        "recommended": _plan(rec),
        "within_budget": _plan(report.within_budget) if report.within_budget else None,
        "current": _plan(report.current),
        "slope_noise_urad": _number(1e6 * rec.noise_mm / (2.0 * de)),
        "ranges": {
            "unambiguous_mm": _number(rng.unambiguous_mm),
            "screen_mm": {d: _number(v) for d, v in rng.screen_mm.items()},
            "screen_point_mm": [_number(v) for v in rng.screen_point_mm],
            "slope_range_mrad": {d: _number(v) for d, v in rng.slope_range_mrad.items()},
            "dent_shift_mm": _number(rng.dent_shift_mm),
            "dent_slope_mrad": _number(rng.dent_slope_mrad),
            "dent_shift_status": rng.shift_status,
            "dent_shift_reason": rng.shift_reason,
            "snr_recommended": _number(_snr(rng.dent_shift_mm, rec.noise_mm)),
            "snr_current": _number(_snr(rng.dent_shift_mm, report.current.noise_mm)),
            "status": rng.status,
            "status_reason": rng.reason,
        },
        "level": _number(probe.level),
        "gain": _number(probe.gain),
        "notes": list(report.notes),
        "seconds": round(probe.seconds, 3),
    }


def _snr(shift: float, noise: float) -> float:
    """The dent's shift over the noise (infinite without noise)."""
    if not math.isfinite(noise):
        return math.nan
    return shift / noise if noise > 0.0 else math.inf


# --------------------------------------------------------------------------- outputs
def coded_scene(report: CodingReport) -> Scene:
    """The report's scene with the recommended coding (``emitter.periods``, ``shifts``);
    an error where there is none (no period is resolved)."""
    rec = report.recommended
    if rec.status == "unresolved":
        raise GlshadeError(f"no coding to write: {rec.reason}")
    return report.scene.updated(emitter={"periods": list(rec.periods_mm), "shifts": rec.shifts})


#: The plot's colours per direction (rendered markers, closed-form lines).
DIRECTION_COLOURS = {"v": (0.0, 0.35, 0.75), "u": (0.85, 0.2, 0.0)}


def write_plot(report: CodingReport, path: Path) -> None:
    """Modulation share against period (log axis, mm; pixels on the top axis): rendered
    per direction (markers; the title says so where they are not read in the dent's
    window), the chain's closed form (lines), a real pixel's box (dashed), the resolved
    level, the finest resolved period and the recommended finest period."""
    from glshade.instruments.figures import new_figure, save_figure

    probe = report.probe
    fig = new_figure(7.0, 4.2)
    ax = fig.add_subplot(1, 1, 1)
    dense = np.geomspace(probe.periods_mm[0], probe.periods_mm[-1], 400)
    for i, d in enumerate(probe.directions):
        colour = DIRECTION_COLOURS.get(d, (0.3, 0.3, 0.3))
        marker = "o" if i == 0 else "x"
        ax.plot(probe.periods_mm, probe.share[i], marker, color=colour, ms=5,
                label=f"rendered, fringes along {d}")  # fmt: skip
        ax.plot(dense, closed_form_share(report.scene, d, dense), "-", color=colour, lw=1.0,
                label=f"closed form along {d} (as rendered)")  # fmt: skip
    w = report.footprint_mm[probe.directions[0]]
    ax.plot(dense, box_share(w, dense), "--", color="0.4", lw=1.0,
            label="real pixel, pinhole: |sin x / x|")  # fmt: skip
    level = report.settings.resolved_share
    ax.axhline(level, color="0.6", lw=0.8, ls=":", label=f"resolved level {level:g}")
    if math.isfinite(report.resolved.period_mm):
        ax.axvline(report.resolved.period_mm, color="0.2", lw=0.8, ls=":",
                   label=f"finest resolved {report.resolved.period_mm:.3g} mm")  # fmt: skip
    if report.recommended.status != "unresolved":
        p1 = report.recommended.periods_mm[0]
        ax.axvline(p1, color=(0.0, 0.6, 0.45), lw=1.0, label=f"recommended p1 {p1:g} mm")
    ax.set_xscale("log")
    ax.set_ylim(-0.02, 1.05)
    ax.set_xlabel("fringe period on the screen (mm)")
    ax.set_ylabel("modulation (share of a sharp mirror's)")
    if math.isfinite(w) and w > 0:
        # matplotlib types the functions' argument as any array-like; it passes arrays
        top = ax.secondary_xaxis("top", functions=(lambda p: p / w, lambda n: n * w))  # type: ignore[operator]
        top.set_xlabel("pixels per period (along the first coded direction)")
    title = report.scene.title()
    if not probe.in_window:
        title += " [outside: over every pixel that sees the screen]"
    ax.set_title(title, fontsize=9)
    ax.grid(True, which="both", alpha=0.25)
    ax.legend(fontsize=7, loc="lower right")
    save_figure(fig, path)
