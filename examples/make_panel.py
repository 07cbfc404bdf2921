"""Generate ``examples/panel.x3p``: a car-door-like painted panel as a profilometer would
deliver it (ISO 25178-72), and its scene file ``examples/panel.toml``.

The map is ``heights[row, column]`` in mm on a square grid ``--spacing`` mm apart, rows
along +z and columns along +x, centred on the origin; the x3p stores it in metres as
float32 (x3p x axis = columns, y axis = rows).

- Shape: gentle double curvature, convex, radii 2500 mm along x and 1800 mm along z:
  ``y = -(x²/(2·2500) + z²/(2·1800))`` mm.
- Orange peel, the waviness of sprayed paint: a Gaussian random field made of N = 200
  cosines (seed 7),

      p(x, z) = c · Σᵢ λᵢ cos(2π/λᵢ · (x cos φᵢ + z sin φᵢ) + ψᵢ),

  with directions φᵢ uniform in [0, π) (with the random phase that covers every
  direction), phases ψᵢ uniform in [0, 2π), and wavelengths λᵢ log-uniform between 1 and
  10 mm. Each amplitude is proportional to its wavelength, so the amplitude spectrum
  rises as λ¹ (falls as 1/k: longer waves are larger; per unit of ln λ the power goes
  as λ²). ``c`` makes the RMS of ``p`` about its mean over the map (Sq) exactly 0.3 µm
  (0.0003 mm).
- No dent: the scene file adds a 4 µm Gaussian dent (σ² = 4 mm²) with its defect table,
  so ``glshade measure examples/panel.toml`` can compare the panel with and without it.

Run ``python examples/make_panel.py`` (about a second) to regenerate both files; the
defaults reproduce the committed ones (640², which the README, docs/BENCHMARKS.md and
docs/figures/example_panel.png describe, about 1.4 MB).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import x3pio

RADIUS_X_MM = 2500.0
RADIUS_Z_MM = 1800.0
RMS_MM = 0.0003
WAVELENGTHS_MM = (1.0, 10.0)
WAVES = 200
SEED = 7
THETA_DEG = 45.0  # the camera of the example scene: the README's figure is rendered so
DENT_MM = 0.004
DENT_SIGMA2_MM2 = 4.0

SCENE = """\
# A car-door-like painted panel (examples/make_panel.py): double curvature, 0.3 µm RMS
# orange peel, and a 4 µm dent. glshade render examples/panel.toml -o panel.png
[camera]
theta_deg = {theta:.1f}

[surface]
kind = "heightmap"
file = "{file}"      # relative to this file; spacing and units come from the x3p
outside = "curtain"

[defect]
dmax = {dmax:g}            # mm
sigma2 = {sigma2:.1f}            # mm²
"""


def panel(size: int, spacing_mm: float) -> np.ndarray:
    """Heights (mm) on ``size`` x ``size`` samples ``spacing_mm`` apart, [row, column] =
    [z, x], centred on the origin."""
    axis = (np.arange(size) - 0.5 * (size - 1)) * spacing_mm
    x, z = np.meshgrid(axis, axis)  # x varies along a row (columns), z down a column (rows)
    shape = -(x**2 / (2 * RADIUS_X_MM) + z**2 / (2 * RADIUS_Z_MM))
    rng = np.random.default_rng(SEED)
    wavelengths = np.exp(rng.uniform(*np.log(WAVELENGTHS_MM), WAVES))
    angles, phases = rng.uniform(0, np.pi, WAVES), rng.uniform(0, 2 * np.pi, WAVES)
    peel = np.zeros_like(x)
    for wavelength, angle, phase in zip(wavelengths, angles, phases, strict=True):
        k = 2 * np.pi / wavelength
        peel += wavelength * np.cos(k * (x * np.cos(angle) + z * np.sin(angle)) + phase)
    peel *= RMS_MM / peel.std()  # Sq: the RMS about the mean
    return shape + peel


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--out",
        type=Path,
        default=Path(__file__).with_name("panel.x3p"),
        help="the .x3p to write; the scene file goes next to it, with .toml",
    )
    parser.add_argument("--size", type=int, default=640, help="samples along each side")
    parser.add_argument("--spacing", type=float, default=0.1, help="sample spacing, mm")
    args = parser.parse_args()
    if args.size < 4 or not args.spacing > 0:
        parser.error("--size must be at least 4 and --spacing above 0")
    heights_m = (panel(args.size, args.spacing) * 1e-3).astype(np.float32)
    step_m = args.spacing * 1e-3
    x3pio.write(args.out, heights_m, x_scale=step_m, y_scale=step_m, z_type=x3pio.DataType.FLOAT32)
    scene = args.out.with_suffix(".toml")
    scene.write_text(
        SCENE.format(theta=THETA_DEG, file=args.out.name, dmax=DENT_MM, sigma2=DENT_SIGMA2_MM2),
        encoding="utf-8",
    )
    print(f"wrote {args.out} ({args.size}x{args.size}, {args.spacing:g} mm) and {scene}")


if __name__ == "__main__":
    main()
