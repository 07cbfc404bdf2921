"""Generate ``examples/panel.x3p``: a car-door-like painted panel as a profilometer would
deliver it (ISO 25178-72), for ``examples/panel.toml``.

- Shape: gentle double curvature, convex, radii 2500 mm along x and 1800 mm along z:
  ``y = -(x²/5000 + z²/3600)`` mm, centred on the origin.
- Orange peel: the waviness of sprayed paint, a Gaussian random field made of 200
  cosines with random directions and phases (seed 7) and wavelengths log-uniform between
  1 and 10 mm, each with an amplitude proportional to its wavelength (the spectrum falls
  as 1/k: longer waves are larger), scaled to 0.3 µm RMS.
- No dent: the scene file adds a 4 µm Gaussian dent (σ² = 4 mm²) with its defect table,
  so ``glshade measure examples/panel.toml`` can compare the panel with and without it.

Run ``python examples/make_panel.py`` (about a second) to regenerate it.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import x3pio

RMS_MM = 0.0003
WAVELENGTHS_MM = (1.0, 10.0)
WAVES = 200
SEED = 7


def panel(size: int, spacing_mm: float) -> np.ndarray:
    """Heights (mm) on ``size`` x ``size`` samples ``spacing_mm`` apart, [row, column] =
    [z, x]."""
    axis = (np.arange(size) - 0.5 * (size - 1)) * spacing_mm
    x, z = np.meshgrid(axis, axis)
    shape = -(x**2 / 5000.0 + z**2 / 3600.0)
    rng = np.random.default_rng(SEED)
    wavelengths = np.exp(rng.uniform(*np.log(WAVELENGTHS_MM), WAVES))
    angles, phases = rng.uniform(0, np.pi, WAVES), rng.uniform(0, 2 * np.pi, WAVES)
    peel = np.zeros_like(x)
    for wavelength, angle, phase in zip(wavelengths, angles, phases, strict=True):
        k = 2 * np.pi / wavelength
        peel += wavelength * np.cos(k * (x * np.cos(angle) + z * np.sin(angle)) + phase)
    peel *= RMS_MM / peel.std()
    return shape + peel


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path(__file__).with_name("panel.x3p"))
    parser.add_argument("--size", type=int, default=640)
    parser.add_argument("--spacing", type=float, default=0.1, help="mm")
    args = parser.parse_args()
    heights_m = panel(args.size, args.spacing) * 1e-3
    x3pio.write(args.out, heights_m.astype(np.float32), x_scale=args.spacing * 1e-3, y_scale=args.spacing * 1e-3,
                z_type=x3pio.DataType.FLOAT32)
    print(f"wrote {args.out} ({args.size}x{args.size}, {args.spacing:g} mm)")


if __name__ == "__main__":
    main()
