"""What ``glshade measure`` prints of a stripe-metric record."""

from __future__ import annotations

from typing import Any

from glshade.metrics.status import concerns
from glshade.scene import Scene


def summary_lines(scene: Scene, record: Any) -> list[str]:
    """The record as a small table, each number with what it means; a number that cannot
    be read says so on its own line (its status, and why): ``glshade measure``."""
    lines: list[str] = []
    cam = scene.camera
    lines.append(
        f"{scene.title()} ({cam.width}x{cam.height}, {scene.render.precision}, "
        f"{scene.render.reflection})"
    )
    ok = record.status == "ok"
    lines.append(
        f"  status                    {record.status}" + ("" if ok else f": {record.status_reason}")
    )

    def flag(column: str) -> str:
        return f"  [{record.status}: not measurable]" if concerns(record.status, column) else ""

    lines.append(
        f"  visibility_px             {record.visibility_px:g}  (the paper's metric, best phase "
        f"{record.best_phase_mm:g} mm){flag('visibility_px')}"
    )
    lines.append(
        f"  visibility_continuous_px  {record.visibility_continuous_px:.2f}  (its limit: finer "
        f"phase step and pixels){flag('visibility_continuous_px')}"
    )
    lines.append(
        f"  deflection_px             {record.deflection_px:.2f}  (how far the rays move)"
        f"{flag('deflection_px')}"
    )
    fold = f"yes, {record.islands} islands at most" if record.folded else "no"
    lines.append(f"  folded                    {fold}")
    lines.append(
        f"  stripe_contrast           {_number(record.stripe_contrast)}  (of the emitter's; 1: "
        "a sharp mirror)"
    )
    if record.noise_floor_px is not None:
        lines.append(
            f"  noise_floor_px            {record.noise_floor_px:g}  (the metric between two noisy "
            "exposures of the defect-free scene)"
        )
    laws = [
        f"deflection {_number(record.deflection_law_px)} px",
        f"visible {_number(record.visibility_law_px)} px",
        f"fold ratio {_number(record.fold_ratio)} (folds above 1)",
    ]
    lines.append(f"  closed forms              {', '.join(laws)}")
    return lines


def _number(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.2f}"
