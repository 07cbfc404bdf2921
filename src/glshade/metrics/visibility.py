"""Defect visibility (docs/study.md): one pipeline from the defect-free analysis of a scene to
the three numbers of any defect measured against it.

:class:`Baseline` holds everything that depends only on the defect-free scene and the
metric settings: its emitter map ``v0``, the kept columns, the pixels that resolve the
stripes, the binarisation level and the labelled stripes of the normal image at the phases
it keeps (:class:`StripeCache`: up to :data:`STRIPE_CACHE_BYTES`, the others labelled again).
:meth:`Baseline.measure` takes a defect's emitter map ``v1`` and returns a
:class:`Visibility`:

- ``visibility_px``: the paper's metric. At each phase of the sweep (``step_mm`` apart,
  below one period) both images are binarised, cut to the central columns, registered,
  and their corresponding contours compared (:mod:`glshade.metrics.contours`); the largest
  distance over the phases.
- ``visibility_continuous_px``: its limit for a vanishing phase step and pixel size, by
  the same contour rules (:func:`glshade.metrics.continuous.visibility_limit`).
- ``deflection_px``: how far the dent moves the emitter map
  (:func:`glshade.metrics.continuous.deflection`).
- ``folded`` (the map runs against itself along a column), ``islands`` (pieces of stripes
  that a fold cuts off: counted, never measured), ``best_phase_mm``.

The study, ``glshade measure``, the viewer and ``glshade accuracy`` all measure through
this class, so they report identical numbers for identical scenes. Nothing here needs a
GL context; :mod:`glshade.measure` renders the maps.

For the mirror and one ray per pixel, the binarised image at phase ``φ`` is exactly
``|wrap(v - φ)| < w*`` (:func:`stripe_half_width`): no phase is ever re-rendered. Other
shading (Blinn-Phong, supersampling) passes the rendered images instead.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any, Protocol

import cv2
import numpy as np

from glshade.errors import GlshadeError
from glshade.metrics import contours as ct
from glshade.metrics.continuous import (
    Deflection,
    Limit,
    StripeLevels,
    deflection,
    visibility_limit,
)
from glshade.metrics.region import Influence, RegionBasis
from glshade.params import Table, param

LEVEL_SOURCES = ("auto", "emitter", "image")


@dataclass(frozen=True)
class MetricSettings(Table):
    """How visibility is measured.

    ``threshold``: binarisation level, a fraction of the emitter peak, in (0, 1);
    ``otsu``: Otsu's level per image instead (rendered images only); ``keep_fraction``:
    the central fraction of the columns kept, (0, 1]; ``step_mm``: phase step of the sweep
    (mm, at most one period); ``max_offset_px``: search radius of the registration
    (pixels); ``min_period_px``: pixels where the defect-free stripe period spans fewer
    pixels than this are left out of the contours (0 keeps every pixel);
    ``limit_upsample`` and ``limit_phases``: rows per pixel row and phases per period of
    the continuous limit's search inside a fold; ``level_from``: what ``threshold`` is a
    fraction of: ``emitter`` (its peak radiance, 1), ``image`` (the defect-free
    image's range: ``dark + threshold (bright - dark)``, its 1st and 99th percentiles over
    the kept pixels at the first phase, as a camera's exposure would be set), ``auto``
    (``image`` when a component scales the radiance: Fresnel, a microfacet lobe, eq. (1)).
    """

    table = "measure"
    table_checks = ()

    threshold: float = param(
        "measure.threshold",
        "",
        0.5,
        "paper: binarisation level, a fraction of what level_from says (the emitter's peak)",
        lo=0.0,
        hi=1.0,
        flag="--threshold",
    )
    otsu: bool = param(
        "measure.otsu",
        "",
        False,
        "paper: Otsu's level per image instead (rendered images only)",
        value_type="boolean",
    )
    keep_fraction: float = param(
        "measure.keep_fraction",
        "",
        0.5,
        "paper: the central fraction of the columns kept",
        lo=0.0,
        hi=1.0,
        closed=True,
        nonzero=True,
        allowed_text="in (0, 1]",
        flag="--keep-fraction",
    )
    step_mm: float = param(
        "measure.step_mm",
        "mm",
        0.25,
        "paper: phase step of the stripe sweep (at most one period)",
        lo=0.0,
        flag="--step",
    )
    max_offset_px: int = param(
        "measure.max_offset_px",
        "px",
        8,
        "paper: search radius of the registration",
        value_type="integer",
        lo=0,
        hi=64,
    )
    min_period_px: float = param(
        "measure.min_period_px",
        "px",
        4.0,
        "paper: pixels where the defect-free stripe period spans fewer pixels than this are "
        "left out of the contours (0 keeps every pixel)",
        lo=0.0,
        closed=True,
    )
    limit_upsample: int = param(
        "measure.limit_upsample",
        "",
        2,
        "paper: rows per pixel row of the continuous limit's search inside a fold",
        value_type="integer",
        lo=1,
        hi=32,
    )
    limit_phases: int = param(
        "measure.limit_phases",
        "",
        32,
        "paper: phases per period of the continuous limit's search inside a fold",
        value_type="integer",
        lo=4,
        hi=1024,
    )
    level_from: str = param(
        "measure.level_from", "", "auto",
        "paper: what threshold is a fraction of: emitter (its peak radiance), image (the "
        "defect-free image's 1st to 99th percentile), auto (image where a component scales "
        "the radiance)",
        value_type="choice", choices=LEVEL_SOURCES,
    )  # fmt: skip

    def phases(self, period_mm: float) -> np.ndarray:
        """Phase shifts of the sweep: 0, step, 2 step, … below one period (a shift of a
        whole period reproduces phase 0). A step larger than the period is an error."""
        if self.step_mm > period_mm:
            raise GlshadeError(
                f"step: must be at most one stripe period ({period_mm:g} mm), got "
                f"{self.step_mm:g} mm"
            )
        count = max(1, math.ceil(period_mm / self.step_mm - 1e-9))
        if count > MAX_PHASES:
            raise GlshadeError(
                f"step: must give at most {MAX_PHASES} phases per stripe period (a step of at "
                "least "
                f"{period_mm / MAX_PHASES:g} mm for the {period_mm:g} mm period), got "
                f"{self.step_mm:g} mm "
                f"= {count} phases"
            )
        return np.arange(count) * self.step_mm


#: Changes whenever the metric's definition changes: results of another version are never
#: mixed into a study or a sweep.
METRIC_VERSION = 3
#: What a binarisation threshold may be a fraction of (:class:`MetricSettings`).
#: Percentiles of the defect-free image taken as its dark and bright levels.
LEVEL_PERCENTILES = (1.0, 99.0)

#: A patch covering more of the cut image than this is compared over the whole image: the
#: region's bookkeeping would cost more than it saves.
PATCH_SHARE = 0.4

#: Bytes of defect-free stripe maps one :class:`Baseline` keeps (:class:`StripeCache`): the
#: study measures every dent of a geometry against them. At 1024² a map takes 2–4 MiB, so
#: the paper's 8 phases are kept up to 2048²; a phase beyond is labelled again each time it
#: is needed (the same map, the same numbers), so a fine sweep holds no state per phase.
STRIPE_CACHE_BYTES = 256 << 20
#: Locks a :class:`StripeCache` labels its phases under (a phase's lock: its hash modulo).
CACHE_LOCKS = 16

#: Most phases one sweep may take (each is a shading and a contour comparison): the
#: paper's sweep is 8 (2 mm period, 0.25 mm step), the finest in the benchmarks 160 (10 mm
#: period, step 1/160 of it).
MAX_PHASES = 2000


def kept_columns(width: int, keep_fraction: float) -> slice:
    """The central ``keep_fraction`` of ``width`` columns (step 3 of the metric)."""
    keep = max(2, round(width * keep_fraction))
    start = (width - keep) // 2
    return slice(start, start + keep)


# --------------------------------------------------------------------------- shading
class Pattern(Protocol):
    """What the metric asks of the emitter (its component's ``pattern(scene)``): a
    pattern repeating along ``v`` every ``period_mm``, its radiance, and the half-width
    of the region a threshold keeps around each stripe (None: not a single interval)."""

    @property
    def period_mm(self) -> float: ...

    def radiance(self, v: np.ndarray, phase_mm: float | None = None) -> np.ndarray: ...

    def binary_half_width(self, threshold: float) -> float | None: ...


def stripe_radiance(v: np.ndarray, pattern: Pattern, phase_mm: float) -> np.ndarray:
    """The pattern's radiance at ``v`` (mm) shifted by ``phase_mm``, as a float32 image
    holds it (0 where ``v`` is NaN): the mirror's picture, shaded from an emitter map."""
    return np.nan_to_num(pattern.radiance(v, phase_mm), nan=0.0).astype(np.float32)


def stripe_half_width(pattern: Pattern, threshold: float) -> float | None:
    """Half-width ``w*`` (mm) of the region ``L > threshold`` around a stripe's centre:
    ``L(v) > threshold`` is then exactly ``|v - phase - k period| < w*`` for the nearest
    ``k``, a binarisation without evaluating a single exponential (None when the pattern
    is not like that: use :func:`stripe_radiance`)."""
    return pattern.binary_half_width(threshold)


def resolved_mask(v0: np.ndarray, period_mm: float, min_period_px: float) -> np.ndarray:
    """Pixels where the sensor resolves the stripes: the defect-free map's local period,
    ``period / |grad v0|`` (pixels), is at least ``min_period_px``.

    Where stripes are narrower than a couple of pixels (near a silhouette, at grazing
    views of curved surfaces) the binarised pattern aliases: sub-pixel changes make
    thin stripes touch diagonally or vanish, so contours change identity and the paper's
    metric would measure that noise instead of the defect. Those pixels are left out of
    both images alike.
    """
    gy, gx = np.gradient(np.asarray(v0, np.float64))
    with np.errstate(invalid="ignore", divide="ignore"):
        local_period = period_mm / np.hypot(gx, gy)
    return np.isfinite(local_period) & (local_period >= min_period_px)


def binarize_v(
    v: np.ndarray, pattern: Pattern, phase_mm: float, half_width_mm: float
) -> np.ndarray:
    """``L(v) > threshold`` from the uv map, given :func:`stripe_half_width` (bool)."""
    w = (v - phase_mm) / pattern.period_mm
    with np.errstate(invalid="ignore"):
        w -= np.round(w)
        return np.abs(w) < half_width_mm / pattern.period_mm


def binarize(image: np.ndarray, settings: MetricSettings, level: float | None = None) -> np.ndarray:
    """Binarise a radiance image: ``> threshold`` of the peak (1), ``> level`` when given,
    or Otsu's level."""
    if settings.otsu:
        pixels = np.clip(np.nan_to_num(image) * 255.0 + 0.5, 0, 255).astype(np.uint8)
        _, binary = cv2.threshold(pixels, 0, 255, cv2.THRESH_BINARY | cv2.THRESH_OTSU)
        return binary > 0
    return np.nan_to_num(image) > (settings.threshold if level is None else level)


def image_level(image: np.ndarray, valid: np.ndarray, threshold: float) -> float:
    """``dark + threshold (bright - dark)`` of an image's pixels where ``valid``: its
    :data:`LEVEL_PERCENTILES` (the stripes' troughs and crests, robust to noise)."""
    values = np.asarray(image, np.float64)[valid]
    values = values[np.isfinite(values)]
    if not values.size:
        return threshold
    dark, bright = np.percentile(values, LEVEL_PERCENTILES)
    return float(dark + threshold * (bright - dark))


# --------------------------------------------------------------------------- the sweep
@dataclass(frozen=True)
class PaperResult:
    """The paper's metric over a phase sweep.

    ``visibility_px``: the largest contour distance; ``best_phase_mm``: where it was
    reached; ``shift``: where it is (``column`` in image coordinates); ``offset_px``: the
    registration offset (dx, dy), whole pixels, found at the first phase and applied at
    every phase; ``islands``: the most islands the defect image showed at any phase;
    ``unpaired``: contour-bearing stripes without a partner at the best phase.
    """

    visibility_px: float
    best_phase_mm: float
    shift: ct.ContourShift
    offset_px: tuple[int, int]
    islands: int
    unpaired: int
    per_phase: tuple[ct.PhaseResult, ...]


def sweep(
    phases: np.ndarray,
    normal_stripes: Callable[[float], ct.StripeMap],
    defect_binary: Callable[[float], np.ndarray],
    edge: np.ndarray | None,
    columns: slice,
    max_offset_px: int,
) -> PaperResult:
    """The metric's steps 1–7 (docs/study.md) on cut images: ``normal_stripes(phase)`` gives
    the defect-free analysis, ``defect_binary(phase)`` the cut defect image (bool); the
    defect image is registered on the normal one at the first phase (images from any
    source: photographs may be offset; rendered pairs are not, see :class:`Baseline`)."""
    results = []
    offset = (0, 0)
    for index, phase in enumerate(phases):
        phase = float(phase)
        normal = normal_stripes(phase)
        defect = defect_binary(phase)
        if index == 0:
            offset = ct.register(normal.labels > 0, defect, max_offset_px)
        results.append(ct.compare(normal, ct.shift_image(defect, *offset), edge, phase))
    return summary(results, columns, offset)


def summary(
    results: list[ct.PhaseResult], columns: slice, offset: tuple[int, int] = (0, 0)
) -> PaperResult:
    """The sweep's result from its phases' comparisons: the largest distance (the first
    phase reaching it), its place in the uncut image, the most islands."""
    best = max(results, key=lambda r: r.distance_px)
    return PaperResult(
        visibility_px=best.distance_px,
        best_phase_mm=best.phase_mm,
        shift=best.shift.in_image(columns.start),
        offset_px=offset,
        islands=max(r.islands for r in results),
        unpaired=best.unpaired,
        per_phase=tuple(results),
    )


def image_visibility(
    normal_images: Callable[[float], np.ndarray],
    defect_images: Callable[[float], np.ndarray],
    period_mm: float,
    settings: MetricSettings = MetricSettings(),
    valid: np.ndarray | None = None,
) -> PaperResult:
    """The paper's metric on radiance images from any source (renders, photographs,
    synthetic arrays), binarised with ``settings``. ``valid`` (bool, optional): the
    region that sees the emitter; without it only the image's top and bottom rows count
    as its border."""
    first = np.asarray(normal_images(0.0))
    columns = kept_columns(first.shape[1], settings.keep_fraction)
    edge = ct.border_pixels(valid[:, columns]) if valid is not None else None
    mask = valid[:, columns] if valid is not None else True

    def normal(phase: float) -> ct.StripeMap:
        return ct.find_stripes(binarize(normal_images(phase), settings)[:, columns] & mask, edge)

    def defect(phase: float) -> np.ndarray:
        return binarize(defect_images(phase), settings)[:, columns] & mask

    return sweep(settings.phases(period_mm), normal, defect, edge, columns, settings.max_offset_px)


# --------------------------------------------------------------------------- one case
class StripeCache:
    """A baseline's defect-free stripe maps by phase: ``make(phase)`` labels one; at most
    ``max_bytes`` of them are kept (:attr:`~glshade.metrics.contours.StripeMap.nbytes`), in
    the order first asked for, never evicted (a sweep asks in order: its first phases stay).
    A phase is labelled under a lock (one of :data:`CACHE_LOCKS`), so threads asking for it
    at once label it once; once a map did not fit, the phases not kept are labelled without.
    """

    def __init__(self, make: Callable[[float], ct.StripeMap], max_bytes: int) -> None:
        self._make = make
        self.max_bytes = max_bytes
        #: bytes of the maps kept
        self.held_bytes = 0
        self._maps: dict[float, ct.StripeMap] = {}
        self._locks = tuple(threading.Lock() for _ in range(CACHE_LOCKS))
        self._count = threading.Lock()
        self._full = False

    def __len__(self) -> int:
        return len(self._maps)

    def __call__(self, phase_mm: float) -> ct.StripeMap:
        key = float(phase_mm)
        found = self._maps.get(key)
        if found is not None:
            return found
        if self._full:
            return self._make(key)
        with self._locks[hash(key) % CACHE_LOCKS]:
            found = self._maps.get(key)
            if found is None:
                found = self._make(key)
                self._keep(key, found)
        return found

    def _keep(self, key: float, stripes: ct.StripeMap) -> None:
        with self._count:
            size = stripes.nbytes
            if self.held_bytes + size > self.max_bytes:
                self._full = True
                return
            self._maps[key] = stripes
            self.held_bytes += size


@dataclass(frozen=True)
class StageSeconds:
    """Where a measurement spent its time (seconds): binarising, the contour analysis,
    and the continuous numbers (deflection and limit)."""

    shade: float = 0.0
    contours: float = 0.0
    continuous: float = 0.0


@dataclass(frozen=True)
class Visibility:
    """The visibility of one defect (docs/study.md), every length in pixels of the image.

    ``visibility_px``, ``visibility_continuous_px``, ``deflection_px``, ``folded``,
    ``islands``, ``best_phase_mm``: see the module docstring; ``offset_px``: the
    registration; ``unpaired_contours``: contour-bearing stripes left without a partner at
    the best phase; ``unresolved_fraction``: the share of kept pixels left out because
    they do not resolve the stripes; ``shift``: where the paper's distance was measured;
    ``displacement_px``: the deflection's map; ``limit``: the continuous limit's details;
    ``noise_floor_px``: with a sensor, the paper's metric between two exposures of the
    defect-free scene (the contour jitter the noise alone makes; None without a sensor);
    ``status``, ``status_reason``: whether the numbers can be read, and why not;
    ``stripe_contrast``: the defect-free stripes' Michelson contrast where the metric
    reads them (:mod:`glshade.metrics.status`; all three set by :mod:`glshade.measure.single`).
    Its row in every table is :meth:`glshade.instruments.record.Measurement.of`.
    """

    visibility_px: float
    visibility_continuous_px: float
    deflection_px: float
    folded: bool
    islands: int
    best_phase_mm: float
    offset_px: tuple[int, int]
    unpaired_contours: int
    unresolved_fraction: float
    shift: ct.ContourShift
    per_phase: tuple[ct.PhaseResult, ...] = field(repr=False)
    displacement_px: np.ndarray = field(repr=False)
    limit: Limit = field(repr=False)
    seconds: StageSeconds = field(default_factory=StageSeconds, repr=False)
    noise_floor_px: float | None = None
    status: str = "ok"
    status_reason: str = ""
    stripe_contrast: float = math.nan


#: Everything a :class:`Visibility` says of its case but its maps and timings: what two
#: analyses of one case (the whole frame and the region of influence) must agree on.
RESULT_FIELDS = (
    "visibility_px",
    "visibility_continuous_px",
    "deflection_px",
    "folded",
    "islands",
    "best_phase_mm",
    "offset_px",
    "unpaired_contours",
    "unresolved_fraction",
    "shift",
    "per_phase",
    "limit",
    "noise_floor_px",
    "status",
    "status_reason",
    "stripe_contrast",
)


def differing_fields(a: Visibility, b: Visibility) -> list[str]:
    """The :data:`RESULT_FIELDS` in which two results of one case differ (NaN equals NaN)."""

    def same(x: Any, y: Any) -> bool:
        if isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y):
            return True
        return bool(x == y)

    return [name for name in RESULT_FIELDS if not same(getattr(a, name), getattr(b, name))]


class Baseline:
    """The defect-free half of the metric for one scene geometry (see the module doc).

    ``v0``: the defect-free emitter map (mm, NaN = no hit); ``pattern``: the emitter's
    stripes (:class:`Pattern`, what its component's ``pattern(scene)`` returns);
    ``normal_images(phase)`` (optional): rendered defect-free images, for shading that is
    not a function of ``v`` (Blinn-Phong, supersampling). Thread-safe: the study measures
    several defects against one baseline from worker threads.

    Each dent is analysed in its region of influence (:mod:`glshade.metrics.region`): the
    contours around the pixels where its binary images differ from these, the deflection at
    the pixels it moves by more than :data:`glshade.metrics.region.SEARCHED_PX`. The numbers
    are those of the whole frame by construction; ``full_frame=True`` analyses the whole
    frame instead (the reference the region is checked against, slower).

    Nothing it holds grows with the number of phases: the defect-free stripe maps are kept
    up to ``stripe_cache_bytes`` (:class:`StripeCache`), and a measurement keeps of each
    phase only its :class:`~glshade.metrics.contours.PhaseResult`.
    """

    def __init__(
        self,
        v0: np.ndarray,
        pattern: Pattern,
        settings: MetricSettings = MetricSettings(),
        normal_images: Callable[[float], np.ndarray] | None = None,
        image_levels: bool = False,
        full_frame: bool = False,
        stripe_cache_bytes: int = STRIPE_CACHE_BYTES,
    ) -> None:
        self.v0 = np.asarray(v0)
        self.full_frame = full_frame
        self.pattern = pattern
        self.settings = settings
        self.normal_images = normal_images
        self.phases = settings.phases(pattern.period_mm)
        self.half_width_mm = stripe_half_width(pattern, settings.threshold)
        if normal_images is None and (self.half_width_mm is None or settings.otsu):
            raise GlshadeError(
                "the metric shades the phases from the emitter map, which needs a fixed threshold "
                "and stripes "
                "narrower than a third of the period (emitter.stripe_sigma); pass rendered images "
                "instead"
            )
        height, width = self.v0.shape
        self.columns = kept_columns(width, settings.keep_fraction)
        if settings.min_period_px > 0:
            self.resolved = resolved_mask(self.v0, pattern.period_mm, settings.min_period_px)
        else:
            self.resolved = np.isfinite(self.v0)
        self.valid = self.resolved[:, self.columns]
        self.edge = ct.border_pixels(self.valid)
        seen = np.isfinite(self.v0[:, self.columns])
        self.unresolved_fraction = (
            float((seen & ~self.valid).sum() / seen.sum()) if seen.any() else 0.0
        )
        self._v0_cut = self.v0[:, self.columns]
        #: The binarisation level of rendered images (None: ``settings.threshold``).
        self.level: float | None = None
        if image_levels and normal_images is not None:
            first = np.asarray(normal_images(float(self.phases[0])))[:, self.columns]
            self.level = image_level(first, self.valid, settings.threshold)
        #: The defect-free stripes by phase, kept up to ``stripe_cache_bytes``.
        self.stripe_cache = StripeCache(self._label_normal, stripe_cache_bytes)
        #: Numbers other modules derive from this analysis alone, computed once (the
        #: stripes' contrast): every dent measured against it shares them.
        self.derived: dict[str, Any] = {}
        self._lock = threading.Lock()  # the region, made once
        self._region: RegionBasis | None = None

    # ---------------------------------------------------------------- images
    def binary(
        self, v: np.ndarray, phase_mm: float, images: Callable[[float], np.ndarray] | None = None
    ) -> np.ndarray:
        """The cut binary image at a phase, from an emitter map ``v`` (or the image
        ``images(phase)``), with the unresolved pixels black."""
        if images is not None:
            binary = binarize(images(phase_mm), self.settings, self.level)[:, self.columns]
        elif self.half_width_mm is not None:  # refused at construction otherwise
            binary = binarize_v(v[:, self.columns], self.pattern, phase_mm, self.half_width_mm)
        else:
            raise GlshadeError("binary: this baseline shades rendered images, give them")
        return binary & self.valid

    def normal_stripes(self, phase_mm: float) -> ct.StripeMap:
        """The defect-free image's stripes at a phase (computed once and shared while the
        :attr:`stripe_cache` has room, else again each time)."""
        return self.stripe_cache(phase_mm)

    def _label_normal(self, phase_mm: float) -> ct.StripeMap:
        return ct.find_stripes(self.binary(self.v0, phase_mm, self.normal_images), self.edge)

    # ---------------------------------------------------------------- metrics
    def at_phase(self, v1: np.ndarray, phase_mm: float) -> ct.PhaseResult:
        """The paper's comparison at one phase (the viewer's live readout); no registration."""
        result = ct.compare(
            self.normal_stripes(phase_mm), self.binary(v1, phase_mm), self.edge, float(phase_mm)
        )
        return replace(result, shift=result.shift.in_image(self.columns.start))

    def paper(
        self, v1: np.ndarray, defect_images: Callable[[float], np.ndarray] | None = None
    ) -> tuple[PaperResult, float]:
        """The paper's metric of a defect, and the seconds spent binarising.

        A rendered pair is not registered (its offset is zero by construction). Unless the
        baseline was made ``full_frame``, each phase is compared in the dent's region of
        influence only (:mod:`glshade.metrics.region`): the same numbers, by construction.
        """
        influence = self.influence(v1) if defect_images is None else None
        return self._paper(v1, defect_images, influence)

    def _paper(
        self,
        v1: np.ndarray,
        images: Callable[[float], np.ndarray] | None,
        influence: Influence | None,
    ) -> tuple[PaperResult, float]:
        shading = 0.0
        box = influence.box if influence is not None and images is None else None
        results = []  # of each phase only its PhaseResult: its maps go with the iteration
        for phase in self.phases:
            phase = float(phase)
            normal = self.normal_stripes(phase)
            start = time.perf_counter()
            if self.full_frame:
                defect = self.binary(v1, phase, images)
                shading += time.perf_counter() - start
                results.append(ct.compare(normal, defect, self.edge, phase))
                continue
            patch = self._patch(normal, v1, phase, box, images)
            shading += time.perf_counter() - start
            results.append(self._compared(normal, phase, patch))
        return summary(results, self.columns), shading

    def region(self) -> RegionBasis:
        """The defect-free map's part of every dent's region (made once, then shared)."""
        with self._lock:
            if self._region is None:
                half = self.half_width_mm
                pattern = self.pattern

                def binary(v: np.ndarray, phase: float) -> np.ndarray:
                    return binarize_v(v, pattern, phase, half or 0.0)

                shaded = self.normal_images is None and half is not None
                self._region = RegionBasis(
                    self._v0_cut,
                    self.phases,
                    pattern.period_mm,
                    half or 0.0,
                    binary if shaded else None,
                )
            return self._region

    def _patch(
        self,
        stripes: ct.StripeMap,
        v1: np.ndarray,
        phase_mm: float,
        box: tuple[slice, slice] | None,
        images: Callable[[float], np.ndarray] | None,
    ) -> ct.Patch | None:
        """Where the defect image differs from the normal one (its ``stripes``) at a phase
        (None: nowhere). From images: the whole frame is binarised; from the map: the
        region's box only."""
        normal = stripes.labels
        if images is not None:
            box = (slice(0, normal.shape[0]), slice(0, normal.shape[1]))
            defect = self.binary(v1, phase_mm, images)
        elif box is None:
            return None
        else:
            assert self.half_width_mm is not None
            rows, cols = box
            cut = slice(self.columns.start + cols.start, self.columns.start + cols.stop)
            defect = binarize_v(v1[rows, cut], self.pattern, phase_mm, self.half_width_mm)
            defect &= self.valid[box]
        differs = defect != (normal[box] > 0)
        rows_at, cols_at = np.flatnonzero(differs.any(axis=1)), np.flatnonzero(differs.any(axis=0))
        if not len(rows_at):
            return None
        inner = slice(rows_at[0], rows_at[-1] + 1), slice(cols_at[0], cols_at[-1] + 1)
        return ct.Patch(
            slice(box[0].start + inner[0].start, box[0].start + inner[0].stop),
            slice(box[1].start + inner[1].start, box[1].start + inner[1].stop),
            np.ascontiguousarray(defect[inner]),
        )

    def _compared(
        self, normal: ct.StripeMap, phase_mm: float, patch: ct.Patch | None
    ) -> ct.PhaseResult:
        """The comparison at a phase of the defect image that is the ``normal`` one with
        ``patch`` written over it (:func:`glshade.metrics.contours.compare_patched`; the
        whole image where that finds no distance above 0)."""
        if patch is not None and patch.binary.size <= PATCH_SHARE * normal.labels.size:
            found = ct.compare_patched(normal, patch, self.edge, phase_mm)
            if found is not None:
                return found
        defect = normal.labels > 0
        if patch is not None:
            defect[patch.rows, patch.cols] = patch.binary
        return ct.compare(normal, defect, self.edge, phase_mm)

    def moved(self, v1: np.ndarray) -> Deflection:
        """The deflection of a defect's map against this one (the whole frame)."""
        return deflection(self.v0, v1, self.columns)

    def influence(self, v1: np.ndarray) -> Influence | None:
        """The dent's region of influence (None for a ``full_frame`` baseline)."""
        if self.full_frame:
            return None
        return self.region().influence(v1[:, self.columns])

    def measure(
        self, v1: np.ndarray, defect_images: Callable[[float], np.ndarray] | None = None
    ) -> Visibility:
        """All three numbers of a defect whose emitter map is ``v1`` (and whose rendered
        images are ``defect_images(phase)``, when the baseline was given images)."""
        if (defect_images is None) != (self.normal_images is None):
            raise GlshadeError(
                "measure: give defect images exactly when the baseline has normal images"
            )
        v1 = np.asarray(v1)
        if v1.shape != self.v0.shape:
            raise GlshadeError(
                f"measure: the defect map has shape {v1.shape}, the baseline {self.v0.shape}"
            )
        start = time.perf_counter()
        influence = self.influence(v1)
        paper, shading = self._paper(v1, defect_images, influence)
        contours_s = time.perf_counter() - start - shading
        start = time.perf_counter()
        moved, limit = self._continuous(v1, influence)
        continuous_s = time.perf_counter() - start
        return Visibility(
            visibility_px=paper.visibility_px,
            visibility_continuous_px=limit.visibility_px,
            deflection_px=moved.deflection_px,
            folded=moved.folded,
            islands=paper.islands,
            best_phase_mm=paper.best_phase_mm,
            offset_px=paper.offset_px,
            unpaired_contours=paper.unpaired,
            unresolved_fraction=self.unresolved_fraction,
            shift=paper.shift,
            per_phase=paper.per_phase,
            displacement_px=moved.displacement_px,
            limit=limit,
            seconds=StageSeconds(shading, contours_s, continuous_s),
        )

    def _continuous(self, v1: np.ndarray, influence: Influence | None) -> tuple[Deflection, Limit]:
        """The deflection and the continuous limit: in the region of influence when the
        moves outside it are provably too small to matter (below a pixel, the deflection
        and the limit found in it), else over the whole frame."""
        valid = None  # where both maps see the emitter: a vanishing pixel cannot alias
        levels = StripeLevels(self.pattern.period_mm, self._limit_half_width())
        search = self.settings.limit_upsample, self.settings.limit_phases
        focus = self.region().focus(influence) if influence is not None else None
        order = self.region().order if not self.full_frame else None
        if focus is not None:
            moved = deflection(self.v0, v1, self.columns, focus, order)
            limit = visibility_limit(
                self.v0, v1, valid, self.columns, levels, moved, *search, focus
            )
            if focus.bound_px < min(1.0, moved.deflection_px, limit.visibility_px):
                return moved, limit
        moved = deflection(self.v0, v1, self.columns, order=order)
        return moved, visibility_limit(self.v0, v1, valid, self.columns, levels, moved, *search)

    def _limit_half_width(self) -> float:
        """The stripes' half-width on the emitter for the continuous limit: the
        threshold's (with images, the same fixed-threshold width of the mirror)."""
        if self.half_width_mm is not None:
            return self.half_width_mm
        return 0.25 * self.pattern.period_mm

    # ---------------------------------------------------------------- pictures
    def stripes_at(
        self,
        v1: np.ndarray,
        phase_mm: float,
        offset_px: tuple[int, int] = (0, 0),
        defect_images: Callable[[float], np.ndarray] | None = None,
    ) -> tuple[ct.StripeMap, ct.StripeMap]:
        """Both images' stripes at a phase, the defect image moved by ``offset_px`` (the
        registration of :meth:`measure`): what the Fig. 9 overlay shows."""
        defect = ct.shift_image(self.binary(v1, phase_mm, defect_images), *offset_px)
        return self.normal_stripes(phase_mm), ct.find_stripes(defect, self.edge)
