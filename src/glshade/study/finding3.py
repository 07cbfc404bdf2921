"""The paper's finding 3 under realistic optics: does any effect the ideal
mirror leaves out make gentle dents more visible from just above the surface?

Visibility against θ for the paper's gentle (σ² 9, 16 mm²) and steep (σ² 1, 4 mm²)
5 µm dents on the flat plate, for the ideal mirror and for each effect alone and all
combined (:data:`VARIANTS`): the paper's eq. (1) roughness, a thin lens focused on the
surface or on the stripes' mirror image, a clear coat's Fresnel reflectance, sensor
noise. Every case goes through the measuring engine (:mod:`glshade.measure.engine`), the
pipeline of ``glshade measure`` and ``glshade sweep``. ``glshade finding3`` writes ``finding3.csv``,
``finding3.png`` and ``finding3.md``; ``glshade paper``'s report quotes the latter.

The numbers are :mod:`glshade.study.finding3_numbers`'; the words are the templates
``templates/finding3_report.md.j2`` and ``finding3_section.md.j2``.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from glshade.errors import GlshadeError
from glshade.files import RESULTS_TABLE_BYTES, atomic_write_bytes, read_regular_text
from glshade.instruments.base import Case
from glshade.measure.executors import LocalExecutor
from glshade.measure.locks import run_lock
from glshade.metrics.status import STATUSES
from glshade.metrics.visibility import MetricSettings
from glshade.scene import Scene, paper_scene
from glshade.study import finding3_numbers as numbers
from glshade.study.finding3_numbers import (
    GENTLE,
    HOLDS_GAIN,
    HOLDS_RHO,
    SIGMA2S,
    Finding3Report,
    Finding3Section,
    finding3_holds,
    readable,
    trend,
)
from glshade.study.templating import render, render_lines

__all__ = [
    "GENTLE",
    "HOLDS_GAIN",
    "HOLDS_RHO",
    "SIGMA2S",
    "THETAS",
    "VARIANTS",
    "finding3_holds",
    "read_rows",
    "readable",
    "render_report",
    "report_section",
    "run",
    "section",
    "trend",
    "write_report",
]

THETAS = (85.0, 75.0, 65.0, 55.0, 45.0, 35.0, 25.0, 15.0, 5.0)
DMAX_MM = 0.005
#: The eq. (1) finish: sigma_h 0.05 µm at 550 nm (a fine-polished paint or ground
#: metal: coherent fraction 27 % seen from 85°, 52 % from 45°, 99 % from 5°).
FINISH = {"height_rms_um": 0.05, "wavelength_um": 0.55}
#: f/22 with 16 aperture rays: the blur disc on the emitter (focused on the surface) is
#: A De / Dc = 1.66 mm, on the surface (focused on the stripes) A De / (Dc + De) = 0.67 mm.
LENS = {"f_number": 22.0, "aperture_samples": 16}
SENSOR = {"full_well_e": 10000.0, "read_noise_e": 5.0, "bit_depth": 12, "seed": 0}
FOCUS_ON_STRIPES_MM = 175.6 + 256.0


@dataclass(frozen=True)
class Variant:
    key: str
    label: str
    changes: Mapping[str, dict[str, Any]]


VARIANTS: tuple[Variant, ...] = (
    Variant("mirror", "ideal mirror (the paper's model)", {}),
    Variant("eq1", "eq. (1) finish, sigma_h 0.05 um, lambda 0.55 um", {"render": FINISH}),
    Variant("lens-surface", "thin lens f/22 focused on the surface", {"camera": LENS}),
    Variant(
        "lens-stripes",
        "thin lens f/22 focused on the stripes' mirror image",
        {"camera": {**LENS, "focus_distance": FOCUS_ON_STRIPES_MM}},
    ),
    Variant(
        "fresnel", "clear coat Fresnel, n 1.5", {"render": {"fresnel": "dielectric", "ior": 1.5}}
    ),
    Variant("sensor", "sensor: 10 000 e- full well, 5 e- read noise, 12 bit", {"sensor": SENSOR}),
    Variant(
        "combined",
        "all of it: eq. (1), lens on the stripes, clear coat, sensor",
        {
            "render": {**FINISH, "fresnel": "dielectric", "ior": 1.5},
            "camera": {**LENS, "focus_distance": FOCUS_ON_STRIPES_MM},
            "sensor": SENSOR,
        },
    ),
    Variant(
        "combined-fixed",
        "all of it at a fixed exposure (1: the bare mirror's stripes fill the range)",
        {
            "render": {**FINISH, "fresnel": "dielectric", "ior": 1.5},
            "camera": {**LENS, "focus_distance": FOCUS_ON_STRIPES_MM, "exposure": 1.0},
            "sensor": SENSOR,
        },
    ),
)

FIELDS = (
    "variant",
    "theta_deg",
    "sigma2_mm2",
    "dmax_mm",
    "visibility_px",
    "visibility_continuous_px",
    "deflection_px",
    "noise_floor_px",
    "status",
    "status_reason",
    "seconds",
)
#: Columns read back as text.
TEXT_FIELDS = ("variant", "status", "status_reason")


def scene_for(variant: Variant, theta: float, sigma2: float, size: int) -> Scene:
    return (
        paper_scene("flat", theta, sigma2, DMAX_MM).with_size(size).updated(**dict(variant.changes))
    )


def run(
    out_dir: Path, size: int = 512, variants=VARIANTS, thetas=THETAS, sigma2s=SIGMA2S, progress=None
) -> Path:
    """Measure every case and write the CSV, the figure and the report (the directory
    locked against a second writer); returns the report."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    with run_lock(out_dir, "glshade finding3"):
        rows = _measure(size, variants, thetas, sigma2s, progress)
        _write_csv(rows, out_dir / "finding3.csv")
        _figure(rows, variants, out_dir / "finding3.png")
        return write_report(rows, variants, size, out_dir / "finding3.md")


def _measure(size, variants, thetas, sigma2s, progress) -> list[dict]:
    """Every case through the measuring engine, in this process (the variants' θ share
    one defect-free analysis over the dents)."""
    cases = [
        Case((variant.key, theta, sigma2), scene_for(variant, theta, sigma2, size))
        for variant in variants
        for theta in thetas
        for sigma2 in sigma2s
    ]
    measured: dict = {}
    with LocalExecutor(threads=1) as executor:
        for key, record, _ in executor.rows(cases, MetricSettings(), False):
            measured[key] = _row(key, record)
            if progress is not None:
                progress(measured[key])
    return [measured[case.key] for case in cases]


def _row(key, record) -> dict:
    variant, theta, sigma2 = key
    return {
        "variant": variant,
        "theta_deg": theta,
        "sigma2_mm2": sigma2,
        "dmax_mm": DMAX_MM,
        "visibility_px": record.visibility_px,
        "visibility_continuous_px": record.visibility_continuous_px,
        "deflection_px": record.deflection_px,
        "noise_floor_px": "" if record.noise_floor_px is None else record.noise_floor_px,
        "status": record.status,
        "status_reason": record.status_reason,
        "seconds": round(sum(record.seconds().values()), 3),
    }


def _write_csv(rows, path: Path) -> None:
    import io

    text = io.StringIO()
    writer = csv.DictWriter(text, FIELDS)
    writer.writeheader()
    writer.writerows(rows)
    atomic_write_bytes(path, text.getvalue().encode(), within=path.parent)


def read_rows(path: Path) -> list[dict]:
    """The rows of ``finding3.csv``, each checked as it enters a report: a known variant
    and status, one line of reason, finite numbers; else one line naming the row."""
    text = read_regular_text(path, "finding3 table", RESULTS_TABLE_BYTES)
    rows = []
    for number, row in enumerate(csv.DictReader(io.StringIO(text)), 2):
        problem = _row_problem(row)
        if problem is not None:
            raise GlshadeError(f"finding3 table {path}: row {number}: {problem}")
        rows.append(
            {k: (v if k in TEXT_FIELDS else float(v) if v != "" else None) for k, v in row.items()}
        )
    return rows


def _row_problem(row: dict) -> str | None:
    """What makes a ``finding3.csv`` row unfit for the report, or None."""
    if set(row) != set(FIELDS) or None in row.values():
        return f"expected the columns {', '.join(FIELDS)}"
    if row["variant"] not in {v.key for v in VARIANTS}:
        return f"unknown variant {row['variant'][:40]!r}"
    if row["status"] not in STATUSES:
        return f"unknown status {row['status'][:40]!r}"
    if len(row["status_reason"]) > 4096 or not row["status_reason"].isprintable():
        return "a status_reason that is not one line of text"
    for key in set(FIELDS) - set(TEXT_FIELDS):
        try:
            value = float(row[key]) if row[key] != "" else 0.0
        except ValueError:
            return f"{key} {row[key][:40]!r} is not a number"
        if not math.isfinite(value):
            return f"{key} {row[key]!r} is not a finite number"
    return None


def _figure(rows, variants, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sigma2s = sorted({r["sigma2_mm2"] for r in rows})
    marked = False
    fig, axes = plt.subplots(1, len(sigma2s), figsize=(4.2 * len(sigma2s), 4.2), sharey=False)
    for ax, sigma2 in zip(np.atleast_1d(axes), sigma2s, strict=False):
        for variant in variants:
            theta, vis = numbers.series(rows, variant.key, sigma2)
            line = ax.plot(
                theta,
                vis,
                marker="o",
                ms=3,
                label=variant.key,
                lw=2.5 if variant is variants[0] else 1.2,
            )[0]
            theta, vis = numbers.series(rows, variant.key, sigma2, measurable=False)
            if len(theta):  # not measurable: hollow, in the variant's colour, off the line
                ax.plot(theta, vis, ls="none", marker="o", ms=6, mfc="none", mec=line.get_color())
                marked = True
        ax.set_title(f"flat, σ² {sigma2:g} mm², dmax 5 µm")
        ax.set_xlabel("θ (deg)")
        ax.invert_xaxis()
    np.atleast_1d(axes)[0].set_ylabel("visibility (px)")
    if marked:
        np.atleast_1d(axes)[-1].plot(
            [], [], ls="none", marker="o", mfc="none", mec="grey", label="not measurable"
        )
    np.atleast_1d(axes)[-1].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))
    fig.tight_layout()
    import io

    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110)
    plt.close(fig)
    atomic_write_bytes(path, buffer.getvalue(), within=path.parent)


def render_report(report: Finding3Report) -> str:
    """``finding3.md``'s text, from its numbers."""
    return render("finding3_report.md.j2", report=report)


def write_report(rows, variants, size: int, path: Path) -> Path:
    """``finding3.md`` at ``path``: the answer, the verdicts on the paper's metric and on
    its continuous limit, the visibility against θ, the noise floors and why."""
    text = render_report(numbers.report(rows, variants, size, VARIANTS[0].key))
    atomic_write_bytes(path, text.encode(), within=path.parent)
    return path


def section(out_dir: Path) -> Finding3Section | None:
    """The numbers the study report quotes, when ``finding3.csv`` is in the study's
    directory (``glshade finding3 --out``); None otherwise."""
    path = Path(out_dir) / "finding3.csv"
    if not path.is_file():
        return None
    rows = read_rows(path)
    present = {r["variant"] for r in rows}
    variants = [v for v in VARIANTS if v.key in present]
    return numbers.section(rows, variants, VARIANTS[0].key)


def report_section(out_dir: Path) -> list[str]:
    """The study report's section on finding 3 under realistic optics, as its lines
    (none when ``finding3.csv`` is not in the study's directory)."""
    found = section(out_dir)
    return [] if found is None else render_lines("finding3_section.md.j2", finding3=found)
