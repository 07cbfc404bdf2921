"""Blinn-Phong's accuracy knob: the shader's closed-form lobe against Monte-Carlo
integration of the lobe (NumPy), both against the oracle's converged quadrature."""

from __future__ import annotations

import statistics
from functools import partial
from typing import cast

import numpy as np

from glshade.components.accuracy import (
    AccuracyBench,
    AccuracyKnob,
    KnobPoint,
    image_errors,
    points_table,
)
from glshade.components.base import SceneView
from glshade.components.reflection.blinn_phong import BlinnPhongTable

#: Blinn-Phong errors are reported away from the emitter's edge too: the closed form does
#: not see a lobe that straddles it (docs/numerics.md).
EDGE_MARGIN_MM = 5.0
#: The surfaces the knob is measured on (the cylinder adds nothing the two do not show).
SURFACES = ("flat", "sphere")


def monte_carlo(bench: AccuracyBench, scene: SceneView, samples: int, seed: int = 1) -> np.ndarray:
    """Blinn-Phong radiance by Monte-Carlo: half vectors drawn from the (n·h)^N lobe
    around the normal, l = reflect(wo, h), self-normalised weights 4 (wo·h) (the
    Jacobian from h to l); a miss of the emitter counts 0. Seeded, so reproducible."""
    rng = np.random.default_rng(seed)
    d, points, normals, hit = bench.hits(scene)
    emitter = scene.active.emitter
    out = np.zeros(len(d))
    n_exp = cast(BlinnPhongTable, scene.render).shininess
    for i in np.nonzero(hit)[0]:
        n = normals[i]
        wo = -d[i]
        helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        e1 = np.cross(n, helper)
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(n, e1)
        u1, u2 = rng.random(samples), rng.random(samples)
        cos_t = u1 ** (1.0 / (n_exp + 1.0))  # pdf ∝ cos^N θ_h dω_h
        sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t**2))
        phi = 2 * np.pi * u2
        h = (
            (np.cos(phi) * sin_t)[:, None] * e1
            + (np.sin(phi) * sin_t)[:, None] * e2
            + cos_t[:, None] * n
        )
        wo_h = h @ wo
        l_dir = 2 * wo_h[:, None] * h - wo
        weight = 4 * np.clip(wo_h, 0.0, None)
        _, v, valid = emitter.coordinates(scene, np.repeat(points[i][None], samples, 0), l_dir)
        radiance = np.where(valid, emitter.radiance(scene, np.nan_to_num(v)), 0.0)
        out[i] = float((weight * radiance).sum() / weight.sum()) if weight.sum() > 0 else 0.0
    return out.reshape(scene.camera.height, scene.camera.width)


class BlinnPhongKnob(AccuracyKnob):
    """The closed form (GPU) against Monte-Carlo at 16 … 1024 samples (NumPy), n = 1e5,
    flat and sphere at θ 45, 24x24."""

    name = "Blinn-Phong"
    joins_frames = True
    defaults = (("image", "Blinn-Phong, image"),)

    def measure(self, bench: AccuracyBench) -> list[KnobPoint]:
        surfaces = [s for s in bench.surfaces if s in SURFACES] or ["flat"]
        scenes = [
            bench.paper_scene(s, 45.0, 4.0, 0.005)
            .with_size(24)
            .updated(render={"reflection": "blinn-phong", "shininess": 1e5})
            for s in surfaces
        ]
        truths = [bench.reference(s, ("image", "uv", "mask")) for s in scenes]
        inside = [
            t.mask
            & (
                np.nan_to_num(np.abs(t.uv), nan=np.inf).max(axis=-1)
                <= np.array(s.emitter.half_size).min() - EDGE_MARGIN_MM
            )
            for s, t in zip(scenes, truths, strict=True)
        ]

        def point(
            label: str, images: list[np.ndarray], seconds: list[float], default: bool = False
        ) -> KnobPoint:
            errors = {"image": 0.0, "image_rms": 0.0, "image_edge": 0.0}
            for image, truth, away in zip(images, truths, inside, strict=True):
                peak, rms = image_errors(image, truth.image, away)
                errors["image"] = max(errors["image"], peak)
                errors["image_rms"] = max(errors["image_rms"], rms)
                edge = image_errors(image, truth.image, truth.mask)[0]
                errors["image_edge"] = max(errors["image_edge"], edge)
            return KnobPoint(self.name, label, statistics.median(seconds), errors, default)

        images, seconds = [], []
        for scene in scenes:
            bench.render(scene)
            t, frame = bench.timed(partial(bench.render, scene), bench.repeats)
            images.append(frame.image)
            seconds.append(t)
        points = [point("closed-form lobe (GPU)", images, seconds, True)]
        for n in (16, 64, 256, 1024):
            images, seconds = [], []
            for scene in scenes:
                t, image = bench.timed(partial(monte_carlo, bench, scene, n), 1)
                images.append(image)
                seconds.append(t)
            points.append(point(f"Monte-Carlo {n} samples (NumPy)", images, seconds))
            bench.log(f"Blinn-Phong: Monte-Carlo {n}")
        return points

    def section(self, points: list[KnobPoint], bench: AccuracyBench) -> list[str]:
        return [
            "## Blinn-Phong: the closed-form lobe against Monte-Carlo",
            "",
            "Against the reference's converged quadrature over the half vector "
            "(`glshade.oracle.tracer`), n = 1e5, flat",
            "and sphere at θ 45, 24x24. Monte-Carlo draws half vectors from the (n·h)^N lobe "
            "(importance sampling,",
            "self-normalised), in NumPy; the closed form runs in the shader. Errors over the "
            "pixels whose mirror ray",
            f"lands at least {EDGE_MARGIN_MM:g} mm inside the emitter, and (last column) over "
            "all: the closed form does",
            "not see a lobe that straddles the emitter's edge, which the sphere's image shows.",
            "",
            *points_table(
                points,
                [
                    ("image", "image max"),
                    ("image_rms", "image RMS"),
                    ("image_edge", "image max incl. the edge"),
                ],
            ),
            "",
        ]
