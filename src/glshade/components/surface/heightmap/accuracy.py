"""The height map's accuracy knob: the spacing of its samples. The paper's sphere and
cylinder sampled into maps, rendered as height maps against the analytic surfaces."""

from __future__ import annotations

import statistics
from functools import partial

import numpy as np

from glshade.components.accuracy import AccuracyBench, AccuracyKnob, KnobPoint, points_table

#: Height-map spacings measured (mm), and the map's extent (±x, ±z mm).
SPACINGS = (1.0, 0.5, 0.25, 0.125, 0.0625)
EXTENT = (30.0, 50.0)


class HeightMapKnob(AccuracyKnob):
    """The uv error of the interpolated map against the analytic surface (fp64 shader of
    each, on the pixels both hit) and the time per frame, against the spacing."""

    name = "height-map spacing"
    figures = (
        (
            "uv",
            "height map: uv error against time per frame",
            "mm on the emitter",
            "accuracy_heightmap.png",
        ),
    )

    def measure(self, bench: AccuracyBench) -> list[KnobPoint]:
        scenes = [
            bench.paper_scene(kind, theta, 4.0, 0.005).with_size(bench.size)
            for kind in ("sphere", "cylinder")
            for theta in (45.0, 15.0)
        ]
        fp64 = {"precision": "fp64"}
        truths = [bench.render(s.updated(render=fp64), ("uv", "mask")) for s in scenes]
        points = []
        for spacing in SPACINGS:
            x = np.arange(-EXTENT[0], EXTENT[0] + 1e-9, spacing)
            z = np.arange(-EXTENT[1], EXTENT[1] + 1e-9, spacing)
            xx, zz = np.meshgrid(x, z)
            for precision in ("fp32", "fp64"):
                worst, seconds = 0.0, []
                for index, (scene, truth) in enumerate(zip(scenes, truths, strict=True)):
                    path = bench.directory / f"map_{index}_{spacing:g}.npy"
                    if not path.exists():
                        np.save(path, scene.active.surface.height(scene, xx, zz))
                    mapped = scene.updated(
                        surface={"kind": "heightmap", "file": str(path), "spacing": (spacing,) * 2},
                        render={"precision": precision},
                    )
                    bench.render(mapped, ("uv", "mask"))
                    t, frame = bench.timed(
                        partial(bench.render, mapped, ("uv", "mask")), bench.repeats
                    )
                    both = truth.mask & frame.mask
                    worst = max(worst, float(np.abs(frame.uv - truth.uv)[both].max()))
                    seconds.append(t)
                label = f"{spacing:g} mm, {precision} ({len(x)}x{len(z)})"
                median = statistics.median(seconds)
                points.append(KnobPoint(self.name, label, median, {"uv": worst}))
            bench.log(f"height map: {spacing:g} mm")
        return points

    def section(self, points: list[KnobPoint], bench: AccuracyBench) -> list[str]:
        fp32 = [p.errors["uv"] for p in points if "fp32" in p.label]
        fp64 = [p.errors["uv"] for p in points if "fp64" in p.label]
        ratios = ", ".join(f"{a / b:.1f}" for a, b in zip(fp64, fp64[1:], strict=False))
        return [
            "## Height maps: the spacing to choose",
            "",
            (
                f"The paper's sphere and cylinder (R 70 mm) at θ 45 and 15, {bench.size}², "
                f"sampled on a ±{EXTENT[0]:g} × ±{EXTENT[1]:g} mm grid and rendered as height "
                "maps (bicubic Catmull-Rom), against the analytic surface (fp64 shader) on the "
                "pixels both hit; worst over the four scenes, median time per frame. The "
                "interpolant's slope error falls as the spacing squared: in fp64 by "
                f"{ratios} per halving. In fp32 it stops falling at about {min(fp32):.1g} mm, "
                "the spline's float arithmetic at the grazing view (the analytic sphere's fp32 "
                "shader errs by about 1.4e-4 mm on the same pixels): below the spacing where "
                "the two meet, a finer map costs memory and buys nothing in fp32, and fp64 is "
                "the way to a closer match."
            ),
            "",
            *points_table(points, [("uv", "uv max (mm)")]),
            "",
            "![height map error against time](figures/accuracy_heightmap.png)",
            "",
        ]
