"""The memory a measurement will take, estimated before anything is rendered and held
against the memory budget (``GLSHADE_MEMORY_BUDGET_MB``,
:func:`glshade.budget.memory_budget_from_env`): the renderer's buffers and the
analysis together.

Nothing the analysis holds grows with the number of phases (a phase's images and stripe
maps go with its iteration, :class:`~glshade.metrics.visibility.Baseline`), so the estimate
is a sum of bytes per pixel: the renderer's buffers (its own
:func:`~glshade.gpu.renderer.frame_bytes`, of every output set a case renders), the
analysis of a case, and the defect-free stripe maps a baseline keeps
(:class:`~glshade.metrics.visibility.StripeCache`, sized to what the budget leaves).

The coefficients below are the largest numbers measured (tracemalloc peaks of the
analysis and peak RSS of ``glshade measure``, docs/robustness.md), rounded up: the
estimate is meant to be above what a run takes, never below.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from glshade.errors import GlshadeError
from glshade.metrics.visibility import STRIPE_CACHE_BYTES, MetricSettings, kept_columns
from glshade.scene import Scene

#: The paper metric's analysis of one case, per pixel of the frame: the emitter maps, the
#: resolved mask and its border, the region's basis (measured: 40–45).
MAP_BYTES_PER_PIXEL = 48
#: … and per pixel of the kept columns, the larger of the deflection's whole-frame search
#: (measured: 127 for a dent whose region is the whole image) and, per row sample of the
#: continuous limit (``limit_upsample``), a fold window as large as the kept image
#: (measured: 58 a sample).
CUT_BYTES_PER_PIXEL = 136
FOLD_BYTES_PER_SAMPLE = 64
#: Rendered images (a lens, a lobe, Fresnel, a sensor) add, per pixel: the phase's image,
#: its binarisation and a sensor's development.
IMAGE_BYTES_PER_PIXEL = 64
#: A defect-free stripe map takes at most this per kept pixel (labels, the runs of every
#: column, the per-label tables: 4 + 20 + 10, with a stripe on every other row).
STRIPE_MAP_BYTES_PER_PIXEL = 36
#: The analysis's share that does not grow with the pixels (tables, the interpreter's
#: working arrays).
FIXED_BYTES = 16 << 20
#: An emitter map waiting for the engine's analysis threads, with the result it becomes
#: (its displacement map) and the per-case figures: bytes per pixel.
WAITING_BYTES_PER_PIXEL = 12

#: Phase measuring's coefficients are fitted to the peak resident memory of
#: :func:`glshade.instruments.pmd.station.measure_pmd_scene` above a process that has
#: imported glshade and opened its GL context (sampled every 10 ms through the whole
#: case: 256² to 1024², 24 to 252 frames, 3 and 5 periods a direction, one and two
#: directions, with and without a sensor; docs/coding.md), rounded up, and the
#: per-period terms to the memory the decoding holds (3000 periods at 72² and 85² took
#: 25 % more than the fitted estimate): the estimate lies 14-45 % above every run
#: measured.
#: Per pixel: the nominal geometry, both exact maps, the decoded points, slopes, heights.
PMD_BYTES_PER_PIXEL = 160
#: … per pixel, map (screen coordinate x period: the maps are held for both coordinates,
#: (u, v), whichever the sequence codes) and decoding held: the float32 modulation,
#: offset and wrapped phase. At the peak, while the case's sequence is decoded, the
#: baseline's decoding and the case's are held, and with a sensor the baseline's twin.
PMD_BYTES_PER_MAP = 12
#: … per pixel and period: the decoder's float64 work on one direction's periods (the sine
#: and cosine sums, the offset, the wrapped phase, the modulation, a temporary and the
#: validity masks: 48 and more; measured 42-48).
PMD_DECODE_BYTES_PER_PERIOD = 56
#: … per pixel and frame: the case's rendered sequence (float32), and with a sensor its
#: recorded copy (measured together: 7.1 a frame; the sensor's copy alone: 4.0). The
#: layers a draw renders and reads back are the renderer's (:func:`render_bytes`).
#: Measured per period (tracemalloc peaks of
#: :func:`~glshade.instruments.pmd.station.measure_pmd_scene`
#: at 48², 10 to 160 periods, two directions, four shifts: eight frames a period): 122
#: bytes a pixel without a sensor, 175 with one, where these coefficients give 136 and
#: 192; one direction, three shifts: 108 and 144, given 116 and 152
#: (``tests/test_hostile_input_bounds.py`` holds the estimate's growth above the peak's).
PMD_BYTES_PER_FRAME = 4
#: … per pixel and shift: the finest period's frames of a direction in float64, and their
#: sums' copy, while the result's modulation share is taken (measured: 16-17).
PMD_BYTES_PER_SHIFT = 16
#: A finished case's maps, per pixel (decoded, exact and error points, slopes, heights,
#: masks), beside its modulation and wrapped phase (8 a map) and its recorded sequence
#: (4 a frame).
PMD_RESULT_BYTES_PER_PIXEL = 64
#: Phase measuring's share that does not grow with the pixels (measured: 101-105 MiB):
#: the libraries the analysis loads (SciPy's sparse solver and fits, 44 MiB), the
#: sequence's shader compiled, the height grid's solve and the fitted Gaussian.
PMD_FIXED_BYTES = 112 << 20

GIB = float(1 << 30)


@dataclass(frozen=True)
class MemoryEstimate:
    """Bytes a measurement takes at most: ``frame_bytes`` the renderer's buffers,
    ``analysis_bytes`` the analysis (all its threads), ``cache_bytes`` the stripe maps a
    baseline may keep (sized to what the budget leaves, never refused for)."""

    frame_bytes: int
    analysis_bytes: int
    cache_bytes: int = 0

    @property
    def required_bytes(self) -> int:
        """What the budget must hold: the renderer and the analysis."""
        return self.frame_bytes + self.analysis_bytes


def render_bytes(
    scene: Scene, output_sets: tuple[tuple[str, ...], ...], frame_count: int = 0
) -> int:
    """The renderer's buffers for every output set a case renders (the renderer keeps the
    targets of each): :func:`glshade.gpu.renderer.frame_bytes`, with the sums of a frame
    traced over several draws where a default renderer's loop budget splits its samples."""
    from glshade.gpu.renderer import (
        MAX_FRAMES_PER_DRAW,
        drawn_features,
        frame_bytes,
        pixel_samples,
        sampled,
        samples_per_draw,
    )

    total = 0
    cam = scene.camera
    for outputs in output_sets:
        count = min(frame_count, MAX_FRAMES_PER_DRAW) if "frames" in outputs else 0
        features = drawn_features(scene, outputs, count)
        split = samples_per_draw(scene, frame_count=count) < pixel_samples(scene)
        total += frame_bytes(
            cam.width,
            cam.height,
            features.outputs,
            scene.render.precision,
            summed=sampled(features) and split,
            frame_count=count,
        )
    return total


def paper_estimate(
    scene: Scene, settings: MetricSettings, threads: int = 1, waiting: int = 0
) -> MemoryEstimate:
    """The paper metric's memory for ``scene`` with ``threads`` cases analysed at once and
    ``waiting`` emitter maps queued for them (the engine's; one case: 1 and 0). The stripe
    cache is not in it: :func:`stripe_cache_bytes` sizes it from what is left."""
    cam = scene.camera
    pixels = cam.width * cam.height
    cut = kept_columns(cam.width, settings.keep_fraction)
    cut_pixels = cam.height * (cut.stop - cut.start)
    per_cut = max(CUT_BYTES_PER_PIXEL, FOLD_BYTES_PER_SAMPLE * settings.limit_upsample)
    case = MAP_BYTES_PER_PIXEL * pixels + per_cut * cut_pixels
    outputs: tuple[tuple[str, ...], ...] = (("uv",),)
    if not scene.active.shades_from_emitter_map(scene):  # rendered images, not the map
        case += IMAGE_BYTES_PER_PIXEL * pixels
        outputs += (("image",),)
    analysis = FIXED_BYTES + threads * case + waiting * WAITING_BYTES_PER_PIXEL * pixels
    return MemoryEstimate(render_bytes(scene, outputs), analysis)


def stripe_cache_bytes(
    scene: Scene, settings: MetricSettings, estimate: MemoryEstimate, budget_bytes: int
) -> int:
    """Bytes of defect-free stripe maps a baseline may keep: all its phases' at most, at
    most :data:`~glshade.metrics.visibility.STRIPE_CACHE_BYTES`, at most what the budget
    leaves beside ``estimate``."""
    cam = scene.camera
    cut = kept_columns(cam.width, settings.keep_fraction)
    per_map = STRIPE_MAP_BYTES_PER_PIXEL * cam.height * (cut.stop - cut.start)
    phases = len(settings.phases(scene.active.emitter.pattern(scene).period_mm))
    left = budget_bytes - estimate.required_bytes
    return max(0, min(STRIPE_CACHE_BYTES, phases * per_map, left))


def pmd_estimate(scene: Scene, results: int = 0) -> MemoryEstimate:
    """Phase measuring's memory for ``scene``: the fringe sequence of ``directions x
    periods x shifts`` frames and the white, decoded for the case and its defect-free twin
    (with a sensor twice, with two seeds); and ``results`` finished cases still held (the
    engine's caller holds the last one while the next is measured) with their maps and
    recorded sequences."""
    from glshade.components.emitter.fringes.table import fringes_of

    em, cam = fringes_of(scene), scene.camera
    maps = 2 * len(em.periods)  # the per-direction maps hold both coordinates, (u, v)
    frames = len(em.directions) * len(em.periods) * em.shifts
    records = scene.active.records(scene)
    decodings = 3 if records else 2  # the baseline's (and its twin's) and the case's
    per_pixel = PMD_BYTES_PER_PIXEL + PMD_BYTES_PER_MAP * maps * decodings
    per_pixel += PMD_DECODE_BYTES_PER_PERIOD * len(em.periods)
    per_pixel += PMD_BYTES_PER_FRAME * (frames + 1) + PMD_BYTES_PER_SHIFT * em.shifts
    if records:  # the recorded copy of the sequence
        per_pixel += PMD_BYTES_PER_FRAME * frames
    per_pixel += results * (PMD_RESULT_BYTES_PER_PIXEL + 8 * maps + 4 * (frames + 1))
    analysis = PMD_FIXED_BYTES + per_pixel * cam.width * cam.height
    renders = (("frames", "uv"), ("distance",))
    return MemoryEstimate(render_bytes(scene, renders, frames + 1), analysis)


def check_memory(
    scene: Scene,
    estimate_of: Callable[[Scene], MemoryEstimate],
    budget_bytes: int,
    measured_as: str,
    or_else: str = "",
) -> MemoryEstimate:
    """``estimate_of(scene)``, or a GlshadeError of one line when the renderer and the
    analysis would need more than ``budget_bytes``: what the user gave (the size, and
    ``measured_as``: the phases or frames, the rays per pixel), what it needs, and the
    largest ``--size`` that fits (``or_else``: what else would)."""
    estimate = estimate_of(scene)
    if estimate.required_bytes <= budget_bytes:
        return estimate
    cam = scene.camera
    fits = largest_size(scene, estimate_of, budget_bytes)
    advice = f"at most --size {fits} fits" if fits else "no --size fits"
    raise GlshadeError(
        f"camera.width x camera.height (--size): {cam.width} x {cam.height} pixels measured "
        f"{measured_as} need about {size_text(estimate.required_bytes)} (renderer "
        f"{size_text(estimate.frame_bytes)}, analysis {size_text(estimate.analysis_bytes)}), "
        f"more than the memory budget of {budget_bytes / (1 << 20):.0f} MiB "
        f"(GLSHADE_MEMORY_BUDGET_MB); {advice}{or_else}"
    )


def size_text(count: int) -> str:
    """Bytes as the refusal writes them: GiB with two decimals from 1 GiB, else MiB."""
    return f"{count / GIB:.2f} GiB" if count >= GIB else f"{count / (1 << 20):.0f} MiB"


def largest_size(
    scene: Scene, estimate_of: Callable[[Scene], MemoryEstimate], budget_bytes: int
) -> int | None:
    """The largest ``--size`` (pixels across, the same field of view) whose estimate fits
    ``budget_bytes``, below the scene's own; None when not even 16 pixels do."""
    low, high = 16, max(scene.camera.width, scene.camera.height)
    if estimate_of(scene.with_size(low)).required_bytes > budget_bytes:
        return None
    while high - low > 1:  # the estimate grows with the size: low fits, high does not
        middle = (low + high) // 2
        fits = estimate_of(scene.with_size(middle)).required_bytes <= budget_bytes
        low, high = (middle, high) if fits else (low, middle)
    return low


def paper_terms(scene: Scene, settings: MetricSettings, threads: int = 1) -> str:
    """How the paper's metric measures ``scene``, as the refusal names it."""
    phases = len(settings.phases(scene.active.emitter.pattern(scene).period_mm))
    several = f", {threads} analysis threads (--threads)" if threads > 1 else ""
    return (
        f"by the paper's metric (--step {settings.step_mm:g} mm: {phases} phases, "
        f"render.supersample {scene.render.supersample}{several})"
    )


def pmd_terms(scene: Scene) -> str:
    """How phase measuring measures ``scene``, as the refusal names it."""
    from glshade.components.emitter.fringes.table import fringes_of

    em = fringes_of(scene)
    frames = len(em.directions) * len(em.periods) * em.shifts
    return (
        f"by phase measuring ({frames} frames: {len(em.directions)} directions x "
        f"{len(em.periods)} periods x {em.shifts} emitter.shifts, render.supersample "
        f"{scene.render.supersample})"
    )


def check_paper(
    scene: Scene, settings: MetricSettings, budget_bytes: int, threads: int = 1, waiting: int = 0
) -> MemoryEstimate:
    """:func:`check_memory` of the paper metric (:func:`paper_estimate`), with the stripe
    cache the budget leaves (:func:`stripe_cache_bytes`)."""

    def estimate_of(at: Scene) -> MemoryEstimate:
        return paper_estimate(at, settings, threads, waiting)

    terms = paper_terms(scene, settings, threads)
    found = check_memory(scene, estimate_of, budget_bytes, terms)
    cache = stripe_cache_bytes(scene, settings, found, budget_bytes)
    return MemoryEstimate(found.frame_bytes, found.analysis_bytes, cache)


def check_pmd(scene: Scene, budget_bytes: int, results: int = 0) -> MemoryEstimate:
    """:func:`check_memory` of phase measuring (:func:`pmd_estimate`)."""

    def estimate_of(at: Scene) -> MemoryEstimate:
        return pmd_estimate(at, results)

    fewer = ", or fewer frames (emitter.shifts, emitter.periods, emitter.directions)"
    return check_memory(scene, estimate_of, budget_bytes, pmd_terms(scene), fewer)
