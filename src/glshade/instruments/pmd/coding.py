"""Choosing a PMD station's fringe coding for a scene (docs/coding.md).

A station designer asks, for one part and one camera:

1. the finest fringe period the imaging chain resolves: every pixel averages the fringe
   over its footprint on the screen (and a lens over its blur disc), so the modulation
   falls as the period shrinks. The defect-free scene is rendered with
   :data:`PROBE_SHIFTS` phase steps of a log-spaced series of candidate periods (one
   trace per :data:`~glshade.gpu.renderer.MAX_FRAMES_PER_DRAW` frames: every ray shaded
   for every frame) and each period's modulation is decoded with the N-step formula, as
   a share of what a sharp mirror shows (the screen's fundamental times the pixel's
   response to the screen's white), its median taken in the dent's window
   (:func:`~glshade.metrics.status.dent_window`). Beside it, the closed form of a box
   pixel footprint sampled as the renderer samples it (``render.supersample``) times a
   lens's blur disc (:func:`~glshade.metrics.coding_laws.closed_form_share`).
2. how many phase shifts ``N`` reach a target noise and which period ladder unwraps
   safely: the noise law ``σ_s = p1 / 2π · sqrt(2 / N) · σ_I / B`` (``σ_I`` the
   sensor's noise at the pixel's mean level, ``B`` its modulation, both recorded
   units), and ratios between neighbouring periods small enough that a period's phase
   error times the ratio stays below π with a margin of :attr:`CodingSettings.margin_sigmas`.
3. the ranges: the unambiguous range (the coarsest period), the slopes the screen can
   measure around the dent's screen point, and the dent's shift against the noise.
4. whether ``glshade measure --method pmd`` can measure the coding within the memory
   budget (:func:`glshade.instruments.memory.pmd_estimate`): where it cannot, the budget it
   needs (``GLSHADE_MEMORY_BUDGET_MB``), the least noise within the budget
   (:func:`within_budget`) and the largest image that fits, before anything is measured.

Everything here is per coded direction (``emitter.directions``); a scene of stripes is
measured with the fringes on the same screen
(:meth:`~glshade.instruments.base.Instrument.prepared`).
The closed forms are :mod:`glshade.metrics.coding_laws`; the outputs (JSON, the coded
scene, the plot) :mod:`glshade.instruments.pmd.coding_files`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from glshade.budget import memory_budget_from_env
from glshade.components.emitter.fringes.table import (
    MAX_SHIFTS,
    FringeFrame,
    FringesTable,
    fringes_of,
)
from glshade.errors import GlshadeError
from glshade.frame import Frame, Region
from glshade.instruments.memory import largest_size, pmd_estimate, size_text
from glshade.instruments.pmd.settings import check_scene
from glshade.metrics.coding_laws import (
    ErrorBudget,
    Resolved,
    blur_mm,
    box_share,
    closed_form_share,
    coded_axis,
    finest_resolved,
    footprint_mm,
    gamma_error_rad,
    ladder,
    quantisation_error_rad,
    quantisation_rms_rad,
    round_up,
    screen_harmonics,
    white_fundamental,
)
from glshade.metrics.physics import pmd_shift_law_check, pmd_shift_mm
from glshade.metrics.status import dent_window
from glshade.oracle.lobe import gaze_share
from glshade.scene import Scene

if TYPE_CHECKING:
    from glshade.gpu.renderer import Renderer

#: Phase steps of the probe's frames (four steps cancel a gamma's 2nd harmonic).
PROBE_SHIFTS = 4
#: The recommended coarsest period is this many times the screen's extent: a little
#: beyond the screen, so the decoder tells a coordinate just below 0 that noise wrapped
#: round from one near the far edge (docs/pmd.md, the guard).
COARSEST_MARGIN = 1.1
#: The most periods a recommended ladder may hold.
MAX_PERIODS = 32
#: Bytes in a MiB, the unit of ``GLSHADE_MEMORY_BUDGET_MB``.
MIB = 1 << 20


@dataclass(frozen=True)
class CodingSettings:
    """What the coding is chosen for. ``target_noise_mm``: the decoded coordinate's
    noise to reach (mm on the screen; None: keep the scene's ``emitter.shifts``);
    ``resolved_share``: a period is resolved where its modulation is at least this share
    of a sharp mirror's; ``margin_sigmas``: the unwrapping's margin (a period's phase
    error, random noise times this plus the systematic bounds, times the ratio to the
    next finer period, stays below π); ``candidates``: probed periods."""

    target_noise_mm: float | None = None
    resolved_share: float = 0.5
    margin_sigmas: float = 6.0
    candidates: int = 24

    def __post_init__(self) -> None:
        target = self.target_noise_mm
        if target is not None and not (math.isfinite(target) and target > 0.0):
            raise GlshadeError(f"target_noise_mm: must be a length > 0 mm, got {target!r}")
        if not 0.0 < self.resolved_share < 1.0:
            raise GlshadeError(f"resolved_share: must be in (0, 1), got {self.resolved_share!r}")
        if not (math.isfinite(self.margin_sigmas) and 1.0 <= self.margin_sigmas <= 20.0):
            raise GlshadeError(f"margin_sigmas: must be in [1, 20], got {self.margin_sigmas!r}")
        if not 8 <= self.candidates <= 96:
            raise GlshadeError(
                f"candidates: must be an integer in [8, 96], got {self.candidates!r}"
            )


# --------------------------------------------------------------------------- the probe
@dataclass(frozen=True)
class Probe:
    """The rendered modulation of the defect-free scene. ``periods_mm`` (C,), per coded
    direction ``share`` (D, C) the median modulation share and ``noise_ratio`` (D, C)
    the root mean square of ``σ_I / B`` (recorded units; 0 without a sensor) over
    ``pixels`` pixels: the dent's window where it sees the screen (``in_window``), else
    every pixel that does. ``screen_point`` (2,) the median screen point (u, v) mm
    those pixels see; ``level`` the median recorded mean level ``A``; ``gain`` the
    exposure; ``seconds`` the render's."""

    directions: tuple[str, ...]
    periods_mm: np.ndarray
    share: np.ndarray
    noise_ratio: np.ndarray
    pixels: int
    in_window: bool
    screen_point: np.ndarray
    level: float
    gain: float
    seconds: float


def probe_periods(scene: Scene, settings: CodingSettings) -> np.ndarray:
    """The candidate periods (mm), log-spaced from one pixel's footprint (where a real
    pixel's modulation vanishes) to :func:`coarsest_period_mm`."""
    widths = [footprint_mm(scene, d) for d in fringes_of(scene).directions]
    finite = [w for w in widths if math.isfinite(w)]
    cam = scene.camera
    flat = (scene.gaze.camera_mm + scene.gaze.screen_mm) * scene.gaze.pitch_mm / cam.focal
    lo = min(finite) if finite else flat
    return np.geomspace(lo, coarsest_period_mm(scene), settings.candidates)


def coarsest_period_mm(scene: Scene) -> float:
    """:data:`COARSEST_MARGIN` times the screen's largest coded extent, rounded up."""
    em = fringes_of(scene)
    extent = max(2.0 * em.half_size[coded_axis(d)] for d in em.directions)
    return round_up(COARSEST_MARGIN * extent)


def probe_frames(em: FringesTable, periods: np.ndarray) -> tuple[FringeFrame, ...]:
    """The probe's frames: direction by direction, period by period, shift by shift."""
    return tuple(
        FringeFrame(
            direction,
            c,
            n,
            float(period),
            2.0 * math.pi * n / PROBE_SHIFTS,
            em.offset,
            em.amplitude,
        )
        for direction in em.directions
        for c, period in enumerate(periods)
        for n in range(PROBE_SHIFTS)
    )


def render_probe(renderer: Renderer, scene: Scene, periods: np.ndarray) -> Probe:
    """Render the probe frames of the defect-free ``scene`` (the white screen and the uv
    map with the first chunk, a chunk of whole periods per trace) and reduce each period
    to its modulation share and noise ratio on the chosen pixels."""
    from glshade.gpu.renderer import MAX_FRAMES_PER_DRAW

    start = time.perf_counter()
    normal = scene.without_defect()
    em = fringes_of(normal)
    frames = probe_frames(em, periods)
    per_chunk = max(1, (MAX_FRAMES_PER_DRAW - 1) // PROBE_SHIFTS) * PROBE_SHIFTS
    shape = (normal.camera.height, normal.camera.width)
    window = dent_window(normal, shape)
    region = Region.of_mask(window)  # the probe reads the dent's window: traced alone
    head = (em.white(), *frames[:per_chunk])
    first = renderer.render(normal, ("frames", "uv"), frames=head, region=region)
    cut = window[region.slices] if region is not None else window
    if region is not None and not _seen(first).any():
        region, cut = None, window  # the window sees no screen: every pixel that does
        first = renderer.render(normal, ("frames", "uv"), frames=head)
    layers = first.output("frames")
    uv = first.output("uv").astype(np.float64)
    white = layers[0].astype(np.float64)
    where, in_window = probe_pixels(normal, uv, white, cut)
    gain = renderer.exposure_gain(normal) if normal.active.records(normal) else 1.0
    fundamental = white_fundamental(em)
    stats: list[tuple[float, float, float]] = []
    stack = layers[1:]
    for offset in range(0, len(frames), per_chunk):
        if offset:
            chunk = frames[offset : offset + per_chunk]
            traced = renderer.render(normal, ("frames",), frames=chunk, region=region)
            stack = traced.output("frames")
        groups = stack[:, where].astype(np.float64).reshape(-1, PROBE_SHIFTS, int(where.sum()))
        for group in groups:
            stats.append(_period_stats(normal, group, white[where], gain, fundamental))
    shape = (len(em.directions), len(periods))
    share, noise, level = (np.array(column).reshape(shape) for column in zip(*stats, strict=True))
    return Probe(
        tuple(em.directions),
        np.asarray(periods, np.float64),
        share,
        noise,
        int(where.sum()),
        in_window,
        np.median(uv[where], axis=0),
        float(np.median(level)),
        float(gain),
        time.perf_counter() - start,
    )


def probe_pixels(
    scene: Scene, uv: np.ndarray, white: np.ndarray, window: np.ndarray | None = None
) -> tuple[np.ndarray, bool]:
    """The pixels the probe reads: the dent's window (``window``, of the maps' shape;
    default: the scene's) where it sees the screen (True), else every pixel that sees it
    (False); an error where none does."""
    seen = np.all(np.isfinite(uv), axis=-1) & np.isfinite(white) & (white > 0.0)
    if not seen.any():
        raise GlshadeError(
            "no pixel sees the screen: the coding cannot be chosen (check camera.theta_deg, "
            "emitter.distance and emitter.half_size)"
        )
    near = (dent_window(scene, seen.shape) if window is None else window) & seen
    return (near, True) if near.any() else (seen, False)


def _seen(frame: Frame) -> np.ndarray:
    """The pixels of a probe's first render that see the lit screen."""
    white = frame.output("frames")[0]
    return np.all(np.isfinite(frame.output("uv")), axis=-1) & np.isfinite(white) & (white > 0)


def _period_stats(
    scene: Scene, frames: np.ndarray, white: np.ndarray, gain: float, fundamental: float
) -> tuple[float, float, float]:
    """One period's ``(N, P)`` radiance samples: the median modulation share (of the
    sharp mirror's ``b_1`` times the pixel's white), the root mean square of ``σ_I / B``
    in recorded units (0 without a sensor) and the median recorded mean level."""
    delta = 2.0 * np.pi * np.arange(PROBE_SHIFTS) / PROBE_SHIFTS
    sine = np.sin(delta) @ frames
    cosine = np.cos(delta) @ frames
    modulation = (2.0 / PROBE_SHIFTS) * np.hypot(sine, cosine)
    level = np.clip(frames.mean(axis=0) * gain, 0.0, 1.0)
    share = float(np.median(modulation / (fundamental * white)))
    variance = intensity_variance(scene, level)
    if not np.any(variance > 0.0):
        return share, 0.0, float(np.median(level))
    with np.errstate(divide="ignore"):
        ratio2 = variance / (modulation * gain) ** 2
    return share, float(math.sqrt(np.mean(ratio2))), float(np.median(level))


def intensity_variance(scene: Scene, level: np.ndarray) -> np.ndarray:
    """The recorded intensity's variance at the mean ``level`` (recorded units): photon
    noise ``A / full_well``, read noise ``(read / full_well)²`` and the sensor's
    quantisation ``q² / 12``; 0 without a sensor (as
    :func:`glshade.instruments.pmd.baseline.predicted_noise_mm`)."""
    sensor = scene.sensor
    if not scene.active.records(scene) or sensor.full_well_e is None:
        return np.zeros_like(level)
    full_well = sensor.full_well_e
    q = 1.0 / (2**sensor.bit_depth - 1)
    return np.maximum(level, 0.0) / full_well + (sensor.read_noise_e / full_well) ** 2 + q * q / 12


def resolution(probe: Probe, level: float) -> tuple[dict[str, Resolved], Resolved]:
    """Each direction's finest resolved period and the coding's (the longest)."""
    each = {
        d: finest_resolved(probe.periods_mm, probe.share[i], level)
        for i, d in enumerate(probe.directions)
    }
    values = list(each.values())
    if any(r.status == "unresolved" for r in values):
        return each, next(r for r in values if r.status == "unresolved")
    longest = max(values, key=lambda r: r.period_mm)
    return each, longest


# --------------------------------------------------------------------------- the noise law
def interpolated(probe: Probe, values: np.ndarray, period_mm: float) -> np.ndarray:
    """Per direction, ``values`` (D, C) at ``period_mm`` (log-linear; NaN below the
    probed range, the coarsest probed value above it)."""
    if period_mm < probe.periods_mm[0] * (1.0 - 1e-9):
        return np.full(len(probe.directions), math.nan)
    x = np.log(probe.periods_mm)
    return np.array([np.interp(math.log(period_mm), x, row) for row in values])


def phase_noise_rad(probe: Probe, period_mm: float, shifts: int) -> np.ndarray:
    """Per direction, the phase noise ``sqrt(2 / N) · rms(σ_I / B)`` (rad)."""
    return math.sqrt(2.0 / shifts) * interpolated(probe, probe.noise_ratio, period_mm)


def coordinate_noise_mm(probe: Probe, period_mm: float, shifts: int) -> float:
    """The decoded coordinate's noise ``p1 / 2π · sqrt(2 / N) · σ_I / B``, pooled over
    the coded directions as their root mean square (what ``pmd_noise_mm`` measures)."""
    phase = phase_noise_rad(probe, period_mm, shifts)
    return float(period_mm / (2.0 * math.pi) * math.sqrt(np.mean(phase**2)))


def shifts_for(probe: Probe, period_mm: float, target_mm: float) -> int:
    """The smallest ``N >= 3`` whose noise at ``period_mm`` is at most ``target_mm``
    (:data:`~glshade.components.emitter.fringes.table.MAX_SHIFTS` + 1 where none is)."""
    at_two = coordinate_noise_mm(probe, period_mm, 2)  # σ ∝ 1 / sqrt(N)
    if not math.isfinite(at_two):
        return MAX_SHIFTS + 1
    needed = max(3, math.ceil(2.0 * (at_two / target_mm) ** 2 - 1e-9))
    while needed > 3 and coordinate_noise_mm(probe, period_mm, needed - 1) <= target_mm:
        needed -= 1
    while needed <= MAX_SHIFTS and coordinate_noise_mm(probe, period_mm, needed) > target_mm:
        needed += 1
    return min(needed, MAX_SHIFTS + 1)


#: The fewest screen pixels a recommended fringe period spans: a fringe of two pixels is
#: the finest a pixelated screen can show (its Nyquist limit).
MIN_SCREEN_PIXELS = 2


def finest_floor_mm(scene: Scene) -> float:
    """The shortest finest period the chooser may recommend on ``scene``'s screen (mm),
    whatever the camera resolves: the one lower bound :func:`best_finest` applies, two of
    the screen's pixels (``emitter.pixel_pitch``; 0 for a continuous screen)."""
    return MIN_SCREEN_PIXELS * fringes_of(scene).pixel_pitch


def best_finest(probe: Probe, resolved: Resolved, level: float, floor_mm: float = 0.0) -> float:
    """The finest period with the least noise among the resolved probed ones (every
    direction's share at least ``level``) not below ``floor_mm``
    (:func:`finest_floor_mm`): the smallest ``p · rms(σ_I / B)``; without a sensor, the
    finest resolved. Rounded up to two significant digits
    (:func:`~glshade.metrics.coding_laws.round_up`)."""
    lowest = max(resolved.period_mm * 0.999, floor_mm)
    ok = np.all(probe.share >= level, axis=0) & (probe.periods_mm >= lowest)
    pooled = np.sqrt(np.mean(probe.noise_ratio**2, axis=0))
    if not np.any(pooled[ok] > 0.0):
        return round_up(max(resolved.period_mm, floor_mm))
    merit = np.where(ok, probe.periods_mm * pooled, np.inf)
    return round_up(float(probe.periods_mm[int(np.argmin(merit))]))


def error_budget(
    probe: Probe, em: FringesTable, periods: tuple[float, ...], shifts: int
) -> ErrorBudget:
    """The :class:`ErrorBudget` of ``periods`` at ``shifts`` steps."""
    harmonics = screen_harmonics(em)
    gamma = gamma_error_rad(harmonics, shifts)
    random, systematic = [], []
    for p in periods:
        random.append(float(np.max(phase_noise_rad(probe, p, shifts))))
        share = float(np.min(interpolated(probe, probe.share, p)))
        systematic.append(quantisation_error_rad(em, share, harmonics[1]) + gamma)
    return ErrorBudget(tuple(periods), tuple(random), tuple(systematic))


def choose_ladder(
    probe: Probe, em: FringesTable, finest: float, coarsest: float, shifts: int, margin: float
) -> tuple[tuple[float, ...], ErrorBudget | None]:
    """The shortest geometric ladder from ``finest`` to ``coarsest`` whose every step
    keeps ``margin`` σ (None: none of up to :data:`MAX_PERIODS` periods does)."""
    for count in range(2, MAX_PERIODS + 1):
        periods = ladder(finest, coarsest, count)
        if any(b <= a for a, b in zip(periods, periods[1:], strict=False)):
            break
        budget = error_budget(probe, em, periods, shifts)
        if min(budget.margins()) >= margin:
            return periods, budget
    return ladder(finest, coarsest, 2), None


# --------------------------------------------------------------------------- the answer
@dataclass(frozen=True)
class CodingPlan:
    """One coding judged: ``periods_mm`` finest first, ``shifts``, its predicted noise
    (mm on the screen, pooled over the directions), the worst unwrapping margin (σ), the
    screen's fixed patterns at the finest period (mm: the quantisation's estimated root
    mean square and its bound, the gamma's aliasing), the finest period's modulation
    share, and a status (``ok``; ``unreachable``: no ``N`` up to
    :data:`MAX_SHIFTS` reaches the target; ``unsafe``: a step's margin is below the
    settings'; ``unresolved``: its finest period is not resolved or below the probe;
    ``over_budget``: ``glshade measure --method pmd`` would need more memory than the
    budget). ``frames`` the sequence's (directions x periods x shifts) and
    ``memory_bytes`` what measuring it needs (:func:`measure_bytes`; 0 where the plan is
    not available)."""

    periods_mm: tuple[float, ...]
    shifts: int
    noise_mm: float
    margin_sigmas: float
    quantisation_mm: float
    quantisation_bound_mm: float
    gamma_mm: float
    share: float
    status: str = "ok"
    reason: str = ""
    frames: int = 0
    memory_bytes: int = 0

    @classmethod
    def unavailable(cls, periods: tuple[float, ...], shifts: int, reason: str) -> CodingPlan:
        """A coding the probe cannot judge (its finest period is not resolved)."""
        nan = math.nan
        return cls(tuple(periods), shifts, nan, nan, nan, nan, nan, nan, "unresolved", reason)

    @property
    def ratios(self) -> tuple[float, ...]:
        p = self.periods_mm
        return tuple(b / a for a, b in zip(p, p[1:], strict=False))

    @property
    def budget_mib(self) -> int:
        """The least ``GLSHADE_MEMORY_BUDGET_MB`` (MiB) under which ``glshade measure
        --method pmd`` measures this coding: its memory, rounded up."""
        return math.ceil(self.memory_bytes / MIB)


@dataclass(frozen=True)
class Ranges:
    """What the coding and the screen can measure around the dent. ``unambiguous_mm``:
    the recommended coarsest period (decodable screen span); ``screen_mm`` per coded
    direction the screen's extent; ``screen_point_mm`` (u, v) the dent's screen point;
    ``slope_range_mrad`` per coded direction the largest slope (either sign) that keeps
    the dent's screen point on the screen, ``(half_size - |point|) / 2 De``;
    ``dent_shift_mm`` the dent's closed-form shift
    (:func:`~glshade.metrics.physics.pmd_shift_mm`) and ``dent_slope_mrad`` the slope
    it means, ``shift / 2 De``, with whether that law holds (``shift_status``:
    ``ok`` or ``grazing``, :func:`~glshade.metrics.physics.pmd_shift_law_check`, and
    ``shift_reason``); ``status``/``reason``: ``outside`` where the dent's window sees no
    screen (its numbers are NaN)."""

    unambiguous_mm: float
    screen_mm: dict[str, float]
    screen_point_mm: tuple[float, float]
    slope_range_mrad: dict[str, float]
    dent_shift_mm: float
    dent_slope_mrad: float
    status: str = "ok"
    reason: str = ""
    shift_status: str = "ok"
    shift_reason: str = ""


@dataclass(frozen=True)
class CodingReport:
    """The answer to a station designer for one scene (see the module's docstring):
    ``budget_bytes`` the memory budget the codings were judged against, and
    ``within_budget`` where the recommended coding exceeds it, the least noise a coding
    of its finest period reaches within it (None otherwise, or where none fits)."""

    scene: Scene
    settings: CodingSettings
    probe: Probe
    closed_form: np.ndarray
    pixel_box: np.ndarray
    footprint_mm: dict[str, float]
    blur_mm: dict[str, float]
    resolved_each: dict[str, Resolved]
    resolved: Resolved
    recommended: CodingPlan
    current: CodingPlan
    ranges: Ranges
    sensor: bool
    notes: tuple[str, ...]
    budget_bytes: int
    within_budget: CodingPlan | None = None


def choose_coding(
    renderer: Renderer, scene: Scene, settings: CodingSettings = CodingSettings()
) -> CodingReport:
    """Render the probe of ``scene`` (a scene of stripes: the fringes on its screen) and
    choose its coding (:class:`CodingReport`)."""
    from glshade.instruments.pmd import PhaseInstrument

    scene = integrating(PhaseInstrument().prepared(scene))
    check_scene(scene)
    periods = probe_periods(scene, settings)
    probe = render_probe(renderer, scene, periods)
    return judge(scene, probe, settings, renderer.memory_budget_bytes)


#: Rays per pixel side the probe traces where the scene samples each pixel at its centre.
PIXEL_RAYS = 4


def integrating(scene: Scene) -> Scene:
    """The scene as a camera's pixels see it: a real pixel integrates the light over its
    area, so a scene sampled at the pixels' centres (``render.supersample`` 1) is probed
    with :data:`PIXEL_RAYS` x :data:`PIXEL_RAYS` rays a pixel (else its point samples
    would resolve fringes down to a pixel's own footprint)."""
    if scene.render.supersample > 1:
        return scene
    return scene.updated(render={"supersample": PIXEL_RAYS})


def judge(
    scene: Scene, probe: Probe, settings: CodingSettings, budget_bytes: int | None = None
) -> CodingReport:
    """The report of a rendered probe: closed forms, resolution, the codings (measurable
    within ``budget_bytes``; default ``GLSHADE_MEMORY_BUDGET_MB``), ranges."""
    em = fringes_of(scene)
    budget = memory_budget_from_env() if budget_bytes is None else budget_bytes
    directions = probe.directions
    closed = np.stack(
        [
            closed_form_share(
                scene, d, probe.periods_mm, gaze_share(scene, coded_axis(d), probe.periods_mm)
            )
            for d in directions
        ]
    )
    box = np.stack([box_share(footprint_mm(scene, d), probe.periods_mm) for d in directions])
    each, resolved = resolution(probe, settings.resolved_share)
    sensor = bool(np.any(probe.noise_ratio > 0.0))
    recommended = recommend(scene, probe, resolved, settings, sensor, budget)
    fallback = None
    if recommended.status == "over_budget":
        fallback = within_budget(scene, probe, recommended, settings, budget)
        recommended = explain_budget(scene, recommended, fallback, budget)
    current = judge_plan(scene, probe, tuple(em.periods), em.shifts, settings, budget)
    return CodingReport(
        scene,
        settings,
        probe,
        closed,
        box,
        {d: footprint_mm(scene, d) for d in directions},
        {d: blur_mm(scene, d) for d in directions},
        each,
        resolved,
        recommended,
        current,
        ranges(scene, probe, recommended),
        sensor,
        notes(scene, probe, settings, sensor),
        budget,
        fallback,
    )


def recommend(
    scene: Scene,
    probe: Probe,
    resolved: Resolved,
    settings: CodingSettings,
    sensor: bool,
    budget_bytes: int,
) -> CodingPlan:
    """The coding for ``settings``: the best resolved finest period, the smallest ``N``
    reaching the target (the scene's own without a target or a sensor), the shortest
    safe ladder to :func:`coarsest_period_mm`; ``over_budget`` where measuring it needs
    more than ``budget_bytes``."""
    em = fringes_of(scene)
    coarsest = coarsest_period_mm(scene)
    if resolved.status == "unresolved":
        return CodingPlan.unavailable((coarsest,), em.shifts, resolved.reason)
    finest = best_finest(probe, resolved, settings.resolved_share, finest_floor_mm(scene))
    shifts, status, reason = em.shifts, "ok", ""
    target = settings.target_noise_mm
    if target is not None and sensor:
        shifts = shifts_for(probe, finest, target)
        if shifts > MAX_SHIFTS:
            shifts, status = MAX_SHIFTS, "unreachable"
            reason = (
                f"no N up to {MAX_SHIFTS} reaches {target:.3g} mm at {finest:g} mm (a "
                "brighter exposure, a larger full well or a finer resolved period does)"
            )
    periods, budget = choose_ladder(probe, em, finest, coarsest, shifts, settings.margin_sigmas)
    plan = judge_plan(scene, probe, periods, shifts, settings, budget_bytes)
    if budget is None and status == "ok":
        status, reason = "unsafe", plan.reason or "no ladder keeps the unwrapping margin"
    if status != "ok":
        return replace(plan, status=status, reason=reason)
    return plan


def judge_plan(
    scene: Scene,
    probe: Probe,
    periods: tuple[float, ...],
    shifts: int,
    settings: CodingSettings,
    budget_bytes: int | None = None,
) -> CodingPlan:
    """``periods`` at ``shifts`` steps judged by the probe: noise, margin, bounds, and
    the memory measuring it needs against ``budget_bytes`` (default
    ``GLSHADE_MEMORY_BUDGET_MB``)."""
    em = fringes_of(scene)
    finest = periods[0]
    share = float(np.min(interpolated(probe, probe.share, finest)))
    if not math.isfinite(share):
        reason = (
            f"its finest period {finest:g} mm is below the probed range "
            f"({probe.periods_mm[0]:.3g} mm and up)"
        )
        return CodingPlan.unavailable(periods, shifts, reason)
    budget = error_budget(probe, em, periods, shifts)
    margin = min(budget.margins()) if len(periods) > 1 else math.inf
    harmonics = screen_harmonics(em)
    scale = finest / (2.0 * math.pi)
    status, reason = "ok", ""
    if share < settings.resolved_share:
        status = "unresolved"
        reason = (
            f"its finest period {finest:g} mm keeps a modulation share of {share:.2f} < "
            f"{settings.resolved_share:g}"
        )
    elif margin < settings.margin_sigmas:
        status = "unsafe"
        reason = (
            f"its worst step unwraps with {margin:.3g} σ of margin < {settings.margin_sigmas:g}"
        )
    plan = CodingPlan(
        tuple(periods),
        shifts,
        coordinate_noise_mm(probe, finest, shifts),
        margin,
        scale * quantisation_rms_rad(em, share, harmonics[1], shifts),
        scale * quantisation_error_rad(em, share, harmonics[1]),
        scale * gamma_error_rad(harmonics, shifts),
        share,
        status,
        reason,
    )
    return with_memory(scene, plan, budget_bytes)


# --------------------------------------------------------------------------- memory
def coded(scene: Scene, periods: tuple[float, ...], shifts: int) -> Scene:
    """``scene`` with the coding ``periods`` (finest first) at ``shifts`` steps."""
    return scene.updated(emitter={"periods": list(periods), "shifts": shifts})


def with_memory(scene: Scene, plan: CodingPlan, budget_bytes: int | None = None) -> CodingPlan:
    """``plan`` with its frames and the memory measuring it needs; ``over_budget`` where
    that exceeds ``budget_bytes`` (default ``GLSHADE_MEMORY_BUDGET_MB``) and nothing else
    is wrong with it."""
    budget = memory_budget_from_env() if budget_bytes is None else budget_bytes
    memory = measure_bytes(scene, plan.periods_mm, plan.shifts)
    frames = len(fringes_of(scene).directions) * len(plan.periods_mm) * plan.shifts
    plan = replace(plan, frames=frames, memory_bytes=memory)
    if plan.status == "ok" and memory > budget:
        return replace(plan, status="over_budget", reason=over_budget_text(scene, memory, budget))
    return plan


def measure_bytes(scene: Scene, periods: tuple[float, ...], shifts: int) -> int:
    """What ``glshade measure --method pmd`` of ``scene`` with this coding needs within
    the memory budget (bytes: :func:`~glshade.instruments.memory.pmd_estimate`, the check
    that command makes before it renders)."""
    return pmd_estimate(coded(scene, periods, shifts)).required_bytes


def over_budget_text(scene: Scene, memory: int, budget: int) -> str:
    """Why a coding cannot be measured within ``budget`` bytes, and the budget it needs."""
    cam = scene.camera
    return (
        f"glshade measure --method pmd needs about {size_text(memory)} for it at "
        f"{cam.width}x{cam.height}, more than the memory budget of {budget / MIB:.0f} MiB: "
        f"run it with GLSHADE_MEMORY_BUDGET_MB={math.ceil(memory / MIB)}"
    )


def explain_budget(
    scene: Scene, plan: CodingPlan, fallback: CodingPlan | None, budget_bytes: int
) -> CodingPlan:
    """``plan``, and where measuring it exceeds ``budget_bytes`` (``over_budget``) what
    else would do, added to its reason: ``fallback``, the least noise within the budget
    (:func:`within_budget`), and the largest ``--size`` that measures ``plan``."""
    if plan.status != "over_budget":
        return plan
    budget = f"{budget_bytes / MIB:.0f} MiB"
    if fallback is None:
        alternatives = [
            f"no coding of {plan.periods_mm[0]:g} mm and 3 or more shifts fits {budget}"
        ]
    else:
        periods = ", ".join(f"{p:g}" for p in fallback.periods_mm)
        alternatives = [
            f"within {budget} the least noise is {fallback.noise_mm:.3g} mm (periods {periods} "
            f"mm, N {fallback.shifts}, {fallback.frames} frames)"
        ]
    fits = largest_size(coded(scene, plan.periods_mm, plan.shifts), pmd_estimate, budget_bytes)
    if fits is not None:
        alternatives.append(f"at most --size {fits} measures it within the budget")
    return replace(plan, reason=f"{plan.reason}; or else: {'; '.join(alternatives)}")


def within_budget(
    scene: Scene, probe: Probe, plan: CodingPlan, settings: CodingSettings, budget: int
) -> CodingPlan | None:
    """The coding of ``plan``'s finest period with the least noise that measuring fits
    within ``budget`` bytes: the most shifts (fewer than ``plan``'s) whose shortest safe
    ladder fits (None: not even 3 shifts do). No coding of that finest period reaches the
    target with fewer frames than ``plan``: the noise fixes the shifts, and the shortest
    safe ladder at those shifts already has the fewest periods (fewer periods need more
    shifts than they save, the unwrapping margin growing only as ``sqrt(N)``)."""
    em = fringes_of(scene)
    finest, coarsest = plan.periods_mm[0], plan.periods_mm[-1]

    def fitting(shifts: int) -> CodingPlan | None:
        periods, safe = choose_ladder(probe, em, finest, coarsest, shifts, settings.margin_sigmas)
        judged = judge_plan(scene, probe, periods, shifts, settings, budget)
        return judged if safe is not None and judged.status == "ok" else None

    low, high = 2, plan.shifts  # fitting(high) is None; low = 2 stands for "none"
    while high - low > 1:  # more shifts take more memory
        middle = (low + high) // 2
        low, high = (middle, high) if fitting(middle) is not None else (low, middle)
    return fitting(low) if low >= 3 else None


def ranges(scene: Scene, probe: Probe, plan: CodingPlan) -> Ranges:
    """The :class:`Ranges` of ``scene`` with the coding ``plan``."""
    em = fringes_of(scene)
    de = scene.gaze.screen_mm
    shift = pmd_shift_mm(scene)
    law = pmd_shift_law_check(scene)
    screen = {d: 2.0 * em.half_size[coded_axis(d)] for d in probe.directions}
    point = (float(probe.screen_point[0]), float(probe.screen_point[1]))
    slopes = {
        d: 1e3 * (em.half_size[coded_axis(d)] - abs(point[coded_axis(d)])) / (2.0 * de)
        for d in probe.directions
    }
    status, reason = "ok", ""
    if not probe.in_window:
        status = "outside"
        reason = (
            "the dent's window sees no screen point (the dent is outside the image or its "
            "rays miss the screen): its screen point and slope range cannot be read"
        )
        slopes = dict.fromkeys(slopes, math.nan)
        point = (math.nan, math.nan)
    return Ranges(
        plan.periods_mm[-1],
        screen,
        point,
        slopes,
        shift,
        1e3 * shift / (2.0 * de),
        status,
        reason,
        law.status,
        law.reason,
    )


def notes(scene: Scene, probe: Probe, settings: CodingSettings, sensor: bool) -> tuple[str, ...]:
    """What the reader should know about how these numbers were made."""
    out = []
    if scene.render.supersample == PIXEL_RAYS:
        out.append(
            f"each pixel is probed with {PIXEL_RAYS} x {PIXEL_RAYS} rays, as a real pixel "
            "integrates the fringes over its area (a scene sampled at the pixels' centres "
            "is probed so; give --supersample to choose another)"
        )
    if not sensor:
        out.append(
            "no sensor: the decoded points carry no random noise (pmd_noise_mm is 0); only "
            "the screen's quantisation errs, a fixed pattern; the shifts stay the scene's "
            "(give a [sensor], e.g. --set sensor.full_well_e=10000, to choose N)"
        )
    elif settings.target_noise_mm is None:
        out.append("no --target-noise: the shifts stay the scene's emitter.shifts")
    if not probe.in_window:
        out.append(
            "the dent's window sees no screen point: the modulation and noise are taken "
            "over every pixel that sees the screen"
        )
    floor = finest_floor_mm(scene)
    if floor > 0.0:
        out.append(
            f"the finest period is at least {MIN_SCREEN_PIXELS} of the screen's "
            f"{fringes_of(scene).pixel_pitch:g} mm pixels, {floor:g} mm (finer fringes are "
            "not shown faithfully)"
        )
    else:
        out.append(
            "the screen has no pixel pitch (emitter.pixel_pitch = 0, continuous): a real "
            f"screen shows no fringe finer than {MIN_SCREEN_PIXELS} of its pixels; give its "
            "pitch to hold the recommendation to it"
        )
    lobe = scene.active.reflection.lobe_std_rad(scene)
    if lobe is not None:
        out.append(
            f"the finish ({scene.active.reflection.finish_name(scene)}) is in the rendered "
            "modulation and in its closed form: its lobe spread on the screen takes "
            "exp(-2π² s² / p²) of a period p (GGX: its own transfer; "
            "docs/finishes-and-screens.md)"
        )
    return tuple(out)
