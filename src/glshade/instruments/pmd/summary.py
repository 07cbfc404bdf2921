"""What ``glshade measure --method pmd`` prints of a record."""

from __future__ import annotations

from typing import Any

from glshade.scene import Scene


def summary_lines(scene: Scene, record: Any) -> list[str]:
    """A PMD record as a small table; a number its status makes unreadable says so on
    its own line (``glshade measure --method pmd``)."""
    lines: list[str] = []
    from glshade.components.emitter.fringes.table import fringes_of
    from glshade.instruments.pmd.status import pmd_concerns

    em, cam = fringes_of(scene), scene.camera
    frames = len(em.directions) * len(em.periods) * em.shifts
    lines.append(
        f"{scene.title()} ({cam.width}x{cam.height}, phase measuring: {frames} frames, "
        f"{len(em.directions)} directions x {len(em.periods)} periods x {em.shifts} shifts, "
        f"finest {em.periods[0]:g} mm)"
    )
    reason = "" if record.status == "ok" else f": {record.status_reason}"
    lines.append(f"  status                  {record.status}{reason}")

    def flag(column: str) -> str:
        return f"  [{record.status}: not measurable]" if pmd_concerns(record.status, column) else ""

    def number(value: float | None, fmt: str) -> str:
        return "n/a" if value is None else format(value, fmt)

    snr = "inf (no sensor: noise-free)" if record.pmd_snr is None else f"{record.pmd_snr:.1f}"
    law_caveat = (
        ""
        if record.pmd_shift_law_status == "ok"
        else f" [{record.pmd_shift_law_status}: {record.pmd_shift_law_reason}]"
    )
    dmax_um, sigma_mm = 1e3 * scene.defect.dmax, scene.defect.sigma_z2**0.5
    rows = [
        ("pmd_shift_mm", f"{number(record.pmd_shift_mm, '.4f')} mm on the screen (closed form "
         f"{number(record.pmd_shift_law_mm, '.4f')}{law_caveat})"),
        ("pmd_noise_mm", f"{number(record.pmd_noise_mm, '.2e')} mm (predicted "
         f"{number(record.pmd_noise_predicted_mm, '.2e')}; noise alone shifts up to "
         f"{number(record.pmd_noise_floor_mm, '.2e')})"),
        ("pmd_snr", snr),
        ("pmd_slope_urad", f"{number(record.pmd_slope_urad, '.1f')} µrad (largest in the dent)"),
        ("pmd_depth_um", f"{number(record.pmd_depth_um, '.3f')} µm reconstructed (true "
         f"{dmax_um:g} µm)"),
        ("pmd_sigma_mm", f"{number(record.pmd_sigma_mm, '.3f')} mm (true {sigma_mm:.3g})"),
        ("decode_rms_mm", f"{number(record.decode_rms_mm, '.2e')} mm (decoded - exact, "
         "defect-free)"),
        ("unwrap_failures", f"{record.unwrap_failures} pixels"),
        ("valid_fraction", f"{record.valid_fraction:.4f} of the pixels that see the screen"),
        ("modulation", f"{number(record.modulation, '.3f')} of a sharp mirror's (the finest "
         "fringe's share, at the dent, else where the screen is seen)"),
    ]  # fmt: skip
    for name, text in rows:
        lines.append(f"  {name:<22}  {text}{flag(name)}")
    return lines
