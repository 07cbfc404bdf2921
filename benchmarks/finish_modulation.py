"""What a glossy finish leaves of a PMD station's fringes: the modulation of the finest
fringe against the finish, per reflection model, rendered beside its closed form
(:mod:`glshade.oracle.lobe`), and what ``glshade measure --method pmd`` then says.

    python benchmarks/finish_modulation.py [--size 128]

prints the Markdown table of docs/finishes-and-screens.md. The station is the paper's flat
plate at θ 45° (the screen 256 mm from the dent), its default coding (2, 16, 128, 1024 mm,
4 shifts, both directions); each finish is given as its reflected direction's angular
spread and set in each model by the same spread (Blinn-Phong: ``N = 4 / std²``;
Beckmann: ``α = std / √2``; GGX: ``α = std / √2``, GGX's scale, its heavy tail beyond).
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from scipy.optimize import brentq

from glshade.components.emitter.fringes.table import FringeFrame
from glshade.gpu.renderer import Renderer
from glshade.instruments.pmd.settings import PmdSettings
from glshade.instruments.pmd.station import measure_pmd_scene
from glshade.oracle.lobe import kernel_transfer, lobe_footprint
from glshade.scene import Scene, paper_scene

#: Representative finishes: the reflected direction's angular standard deviation (mrad).
FINISHES = {
    "polished metal": 0.3,
    "high-gloss clear coat": 1.5,
    "gloss paint": 5.0,
    "satin paint": 40.0,
}
#: The reflection models: render table values from the angular spread (rad).
MODELS = {
    "blinn-phong": lambda std: {"reflection": "blinn-phong", "shininess": 4.0 / std**2},
    "beckmann": lambda std: {"reflection": "beckmann", "roughness": std / math.sqrt(2.0)},
    "beckmann lattice": lambda std: {
        "reflection": "beckmann",
        "roughness": std / math.sqrt(2.0),
        "lobe_method": "lattice",
        "lobe_samples": 256,
    },
    "ggx": lambda std: {"reflection": "ggx", "roughness": std / math.sqrt(2.0)},
    "ggx lattice": lambda std: {
        "reflection": "ggx",
        "roughness": std / math.sqrt(2.0),
        "lobe_method": "lattice",
        "lobe_samples": 256,
    },
}


def rendered_share(renderer: Renderer, scene: Scene, period: float) -> np.ndarray:
    """Each pixel's modulation of a 4-step fringe of ``period`` along v over the displayed
    fringe's fundamental times its white."""
    em = scene.emitter
    steps = 2.0 * np.pi * np.arange(4) / 4
    frames = [
        FringeFrame("v", 0, n, period, float(steps[n]), em.offset, em.amplitude) for n in range(4)
    ]
    layers = renderer.render(scene, ("frames",), frames=(*frames, em.white())).frames
    layers = layers.astype(np.float64)
    sine = np.tensordot(np.sin(steps), layers[:4], 1)
    cosine = np.tensordot(np.cos(steps), layers[:4], 1)
    return 0.5 * np.hypot(sine, cosine) / (em.harmonics(frames[0])[1] * layers[4])


def half_period_mm(kernel: str, scale_mm: float) -> float:
    """The period whose modulation the lobe halves: ``T(2π s / P) = 1/2``."""
    k = brentq(lambda x: float(kernel_transfer(kernel, np.array(x))) - 0.5, 1e-6, 50.0)
    return 2.0 * math.pi * scale_mm / k


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=128)
    size = parser.parse_args().size
    station = (
        paper_scene("flat", theta_deg=45.0).with_size(size).updated(emitter={"kind": "fringes"})
    )
    centre = slice(size // 2 - 8, size // 2 + 8)
    print(
        "| finish (spread) | model | σ or scale on the screen, v | 2 mm fringe kept: closed "
        "form | rendered | period kept at 1/2 | `measure --method pmd` |"
    )
    print("|---|---|---|---|---|---|---|")
    start = time.perf_counter()
    with Renderer() as renderer:
        for finish, mrad in FINISHES.items():
            for model, values in MODELS.items():
                scene = station.updated(render=values(mrad * 1e-3))
                footprint = lobe_footprint(scene, centre, centre)
                assert footprint is not None
                scale = float(np.median(footprint.scale_mm(1)))
                closed = float(np.median(footprint.modulation(1, 2.0)))
                shares = rendered_share(renderer, scene.without_defect(), 2.0)[centre, centre]
                record = measure_pmd_scene(renderer, scene, PmdSettings())
                status = record.status + (
                    f" (modulation {record.modulation:.3g})" if record.status != "ok" else ""
                )
                print(
                    f"| {finish} ({mrad:g} mrad) | {model} | {scale:.3g} mm | {closed:.3g} | "
                    f"{float(np.median(shares)):.3g} | "
                    f"{half_period_mm(footprint.kernel, scale):.3g} mm | {status} |"
                )
    print(f"\n{time.perf_counter() - start:.0f} s at {size}² on this machine")


if __name__ == "__main__":
    main()
