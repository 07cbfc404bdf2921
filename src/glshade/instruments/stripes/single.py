"""Measuring one scene: render its emitter maps and run the visibility pipeline on them.

A case is a pure function of its scene and the metric settings: :func:`measure_scene`
renders the defect-free twin (``dmax = 0``) and the scene itself and measures one against
the other with :class:`glshade.metrics.visibility.Baseline`. A caller that measures many
defects on one geometry (the engine, the viewer) passes the same baseline to each; that
saves the defect-free trace and analysis and changes no number.

Where the picture is a function of the emitter map (the mirror and one ray per pixel
through a pinhole) the images are shaded from the maps; for other shading (Blinn-Phong,
supersampling, a lens, a sensor) the images of every phase are rendered and binarised,
while the continuous numbers keep following the rays (the emitter maps).
"""

from __future__ import annotations

import dataclasses
import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from glshade.errors import GlshadeError
from glshade.metrics.status import assess, stripe_contrast
from glshade.metrics.visibility import (
    STRIPE_CACHE_BYTES,
    Baseline,
    MetricSettings,
    Visibility,
    stripe_radiance,
)
from glshade.scene import Scene

if TYPE_CHECKING:
    from glshade.rendering import Renderer


def emitter_map(renderer: Renderer, scene: Scene) -> np.ndarray:
    """The scene's emitter coordinate ``v`` per pixel (mm, NaN = no hit)."""
    return np.ascontiguousarray(renderer.render(scene, ("uv",)).output("uv")[..., 1])


def shades_from_map(scene: Scene) -> bool:
    """True when the picture is a function of the emitter map: every active component
    says so (a mirror, one ray per pixel through a pinhole, no Fresnel, no sensor)."""
    return scene.active.shades_from_emitter_map(scene)


def phase_images(
    renderer: Renderer, scene: Scene, exposure: int = 0
) -> Callable[[float], np.ndarray]:
    """``phase -> rendered radiance image`` of a scene, for shading that needs images
    (with a sensor: what it records in exposure number ``exposure``)."""

    def image(phase: float) -> np.ndarray:
        frame = renderer.render(scene.with_phase(phase), ("image",), exposure=exposure)
        return frame.output("image")

    return image


def levels_from_image(scene: Scene, settings: MetricSettings) -> bool:
    """True when the binarisation level is taken from the defect-free image's range
    (``settings.level_from``; ``auto``: when a component scales the radiance)."""
    if settings.level_from != "auto":
        return settings.level_from == "image"
    return not scene.active.keeps_emitter_scale(scene)


def baseline_for(
    renderer: Renderer,
    scene: Scene,
    settings: MetricSettings = MetricSettings(),
    stripe_cache_bytes: int = STRIPE_CACHE_BYTES,
) -> Baseline:
    """The defect-free analysis of a scene's geometry (its defect is ignored), keeping up
    to ``stripe_cache_bytes`` of its stripe maps (:class:`~glshade.metrics.visibility.
    StripeCache`)."""
    check_metric_size(scene)
    normal = scene.without_defect()
    images = None if shades_from_map(scene) else phase_images(renderer, normal)
    pattern = scene.active.emitter.pattern(scene)
    return Baseline(
        emitter_map(renderer, normal),
        pattern,
        settings,
        images,
        image_levels=levels_from_image(scene, settings),
        stripe_cache_bytes=stripe_cache_bytes,
    )


def map_baseline(
    scene: Scene,
    v0: np.ndarray,
    settings: MetricSettings,
    stripe_cache_bytes: int = STRIPE_CACHE_BYTES,
) -> Baseline:
    """The defect-free analysis of ``scene``'s geometry from its traced emitter map ``v0``,
    shaded from the map (the engine's fast path, the viewer's live readout)."""
    check_metric_size(scene)
    pattern = scene.active.emitter.pattern(scene)
    return Baseline(v0, pattern, settings, stripe_cache_bytes=stripe_cache_bytes)


def reuses_stripes(scene: Scene) -> bool:
    """Does one measurement of ``scene`` ask for each defect-free stripe map twice? Only
    where the images are rendered and a sensor's noise floor sweeps them again: the maps
    are worth keeping then (each is a render), otherwise :func:`measure_scene` keeps
    none."""
    return not shades_from_map(scene) and scene.sensor.on


#: The fewest pixels across and down the paper's metric reads (the map's gradients and a
#: contour need two pixels each way).
MIN_METRIC_PIXELS = 2


def check_metric_size(scene: Scene) -> None:
    """One line when the scene's image is too small for the paper's metric."""
    camera = scene.camera
    if min(camera.width, camera.height) < MIN_METRIC_PIXELS:
        raise GlshadeError(
            f"--size / camera.width, camera.height: the paper's metric needs at least "
            f"{MIN_METRIC_PIXELS} pixels each way, got {camera.width}x{camera.height}"
        )


def map_baseline_key(scene: Scene) -> str:
    """Scenes shaded from their emitter maps whose keys are equal have the same
    :func:`map_baseline`: the defect-free scene's values, its absent defect (dmax = 0)
    reduced to what the trace reads of it, its features and its centre (the origin of the
    frame every shader computes in). The analysis reads only the map and the emitter's
    pattern, so dents of every width on one geometry share one defect-free analysis."""
    normal = scene.without_defect()
    values = normal.to_dict()
    defect = normal.active.defect
    if not defect.present(normal):
        values["defect"] = {
            "features": defect.features(normal),
            "centre_mm": normal.local_origin().tolist(),
        }
    return json.dumps(values, sort_keys=True, default=str)


def judged(scene: Scene, baseline: Baseline, v1: np.ndarray, result: Visibility) -> Visibility:
    """``result`` with its status: whether its numbers can be read, and why not
    (:func:`glshade.metrics.status.assess`)."""
    found = assess(scene, baseline, v1, result)
    return dataclasses.replace(
        result,
        status=found.status,
        status_reason=found.reason,
        stripe_contrast=baseline_contrast(baseline),
    )


def baseline_contrast(baseline: Baseline) -> float:
    """The defect-free stripes' contrast (:func:`glshade.metrics.status.stripe_contrast`)
    where the metric reads them, once per baseline: every dent on it shares it."""
    contrast = baseline.derived.get("stripe_contrast")
    if contrast is None:
        phase = float(baseline.phases[0])
        if baseline.normal_images is not None:
            image = baseline.normal_images(phase)[:, baseline.columns]
            valid = baseline.valid
        else:  # shaded from the map: every third row and column tells its percentiles
            cut = baseline.v0[::3, baseline.columns][:, ::3]
            image, valid = stripe_radiance(cut, baseline.pattern, phase), baseline.valid[::3, ::3]
        contrast = stripe_contrast(image, valid, baseline.pattern)
        baseline.derived["stripe_contrast"] = contrast
    return contrast


def measure_scene(
    renderer: Renderer,
    scene: Scene,
    settings: MetricSettings = MetricSettings(),
    baseline: Baseline | None = None,
    overlay: str | os.PathLike[str] | None = None,
    v1: np.ndarray | None = None,
) -> Visibility:
    """The three numbers of a scene's defect on an existing renderer.

    ``baseline``: the defect-free analysis of the same geometry and settings, when the
    caller already has it (:func:`baseline_for`). ``overlay``: also write the Fig. 9
    contour overlay at the best phase to this PNG path. ``v1``: the scene's emitter map,
    when the caller has traced it already (:func:`emitter_map`).

    Without a ``baseline``, a case whose renderer's buffers and analysis would exceed the
    renderer's memory budget is refused first, in one line
    (:func:`glshade.instruments.memory.check_paper`).
    """
    if baseline is None:
        from glshade.instruments.memory import check_paper

        estimate = check_paper(scene, settings, renderer.memory_budget_bytes)
        cache = estimate.cache_bytes if reuses_stripes(scene) else 0
        baseline = baseline_for(renderer, scene, settings, cache)
    images = None if shades_from_map(scene) else phase_images(renderer, scene)
    if v1 is None:
        v1 = emitter_map(renderer, scene)
    result = baseline.measure(v1, images)
    if scene.sensor.on:
        again = phase_images(renderer, scene.without_defect(), exposure=1)
        floor = baseline.paper(baseline.v0, again)[0].visibility_px
        result = dataclasses.replace(result, noise_floor_px=floor)
    result = judged(scene, baseline, v1, result)
    if overlay is not None:
        from glshade.instruments.figures import write_overlay

        write_overlay(baseline, v1, result, images, scene.title(), Path(overlay))
    return result
