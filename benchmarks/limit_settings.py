"""How much the continuous limit's own settings matter: the limit of the paper's metric on
the paper's folded scenes (1024²) with the shipped settings (2 samples per row, 32 phases,
then the zooming search) and with finer ones, against a dense reference (8 samples per
row, a 512-phase grid, then the same zoom). Prints a Markdown table.

    python benchmarks/limit_settings.py

About a minute on the 2-core CPU machine.
"""

from __future__ import annotations

import time

import numpy as np

from glshade.gpu.renderer import Renderer
from glshade.instruments.stripes.single import emitter_map
from glshade.metrics.continuous import StripeLevels, visibility_limit
from glshade.metrics.visibility import Baseline
from glshade.scene import paper_scene

CASES = (  # folded cases of Table 1, flat and cylinder, steep to gentle
    ("flat", 5.0, 1.0, 0.005),
    ("flat", 15.0, 1.0, 0.005),
    ("flat", 5.0, 4.0, 0.005),
    ("flat", 25.0, 1.0, 0.005),
    ("flat", 35.0, 1.0, 0.003),
    ("flat", 5.0, 9.0, 0.005),
    ("cylinder", 5.0, 1.0, 0.005),
    ("cylinder", 5.0, 4.0, 0.005),
)
SETTINGS = (
    (2, 32),
    (4, 32),
    (4, 64),
    (8, 64),
)  # (samples per row, phases per period); the first is shipped
REFERENCE = (8, 512)


def limit(baseline: Baseline, v1: np.ndarray, upsample: int, phases: int) -> tuple[float, float]:
    start = time.perf_counter()
    moved = baseline.moved(v1)
    valid = np.isfinite(baseline.v0) & np.isfinite(v1)
    levels = StripeLevels(baseline.emitter.period, baseline.half_width_mm)
    value = visibility_limit(
        baseline.v0, v1, valid, baseline.columns, levels, moved, upsample, phases
    ).visibility_px
    return value, time.perf_counter() - start


def main() -> None:
    rows = []
    with Renderer() as renderer:
        for case in CASES:
            scene = paper_scene(*case)
            baseline = Baseline(emitter_map(renderer, scene.without_defect()), scene.emitter)
            v1 = emitter_map(renderer, scene)
            truth, _ = limit(baseline, v1, *REFERENCE)
            rows.append((case, truth, [limit(baseline, v1, *s) for s in SETTINGS]))
            print(case, truth, flush=True)
    head = " | ".join(f"{u} rows, {p} phases" for u, p in SETTINGS)
    print(f"\n| case | reference ({REFERENCE[0]} rows, {REFERENCE[1]} phases) px | {head} |")
    print("|---|---:|" + "---:|" * len(SETTINGS))
    for (surface, theta, sigma2, dmax), truth, found in rows:
        cells = " | ".join(f"{v - truth:+.4f} ({t:.2f} s)" for v, t in found)
        print(
            f"| {surface} θ {theta:g}° σ² {sigma2:g} {dmax * 1000:g} µm | {truth:.4f} | {cells} |"
        )
    worst = [
        max(abs(found[i][0] - truth) for _, truth, found in rows) for i in range(len(SETTINGS))
    ]
    print(
        "\nlargest difference from the reference: "
        + ", ".join(
            f"{u} rows/{p} phases {w:.4f} px" for (u, p), w in zip(SETTINGS, worst, strict=True)
        )
    )


if __name__ == "__main__":
    main()
