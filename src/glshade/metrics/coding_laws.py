"""The closed forms behind choosing a PMD station's fringe coding (docs/coding.md).

- How much modulation a fringe of period ``p`` keeps through the imaging chain at the gaze
  point: one pixel's footprint on the screen (:func:`footprint_mm`, the stripes' scale of
  :mod:`glshade.components.image_scale` along ``v`` and its sagittal twin along ``u``)
  as a box sampled like the renderer's supersampling (:func:`box_share`), a thin lens's
  blur disc (:func:`blur_mm`, :func:`disc_share`), and their product with what the finish's
  reflection lobe keeps (:func:`closed_form_share`).
- The screen's fixed patterns: its grey levels (:func:`quantisation_rms_rad`,
  :func:`quantisation_error_rad`) and its gamma's harmonics aliased by ``N`` steps
  (:func:`screen_harmonics`, :func:`gamma_error_rad`).
- The finest resolved period of a modulation curve (:func:`finest_resolved`), a period
  ladder (:func:`ladder`) and its unwrapping margin (:class:`ErrorBudget`).

Pure functions of a scene's tables and of numbers; rendering them is
:mod:`glshade.instruments.pmd.coding`'s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from glshade.components.emitter.fringes.table import DIRECTIONS, FringesTable
from glshade.components.image_scale import base_curvatures, emitter_mm_per_row

#: Significant digits the recommended periods are rounded to.
PERIOD_DIGITS = 2


def coded_axis(direction: str) -> int:
    """The screen coordinate a direction's fringes vary along (0: u, 1: v)."""
    return DIRECTIONS.index(direction) ^ 1


def footprint_mm(scene: Any, direction: str) -> float:
    """The screen length (mm) one pixel sees along ``direction``'s coordinate at the gaze
    point: ``(Dc + De) δ m`` with the tangential magnification ``m`` for ``v``
    (:func:`~glshade.components.image_scale.emitter_mm_per_row`) and the sagittal one
    ``1 - 2 κ_s sin θ Dc De / (Dc + De)`` for ``u``; NaN where the base focuses the
    screen (no finite scale)."""
    if direction == "v":
        return emitter_mm_per_row(scene)
    cam = scene.camera
    dc, de = scene.gaze.camera_mm, scene.gaze.screen_mm
    m = 1.0 - 2.0 * base_curvatures(scene)[1] * math.sin(scene.gaze.theta_rad) * dc * de / (dc + de)
    return (dc + de) * scene.gaze.pitch_mm / cam.focal * m if m > 0.0 else math.nan


def blur_mm(scene: Any, direction: str) -> float:
    """The diameter (mm) of a thin lens's blur disc on the screen along ``direction``:
    ``A |L - F| / F`` (``A = focal / f_number``, ``L = Dc + De`` the screen's mirror image,
    ``F`` the focus distance) times the magnification; 0 for a pinhole."""
    cam = scene.camera
    if cam.f_number <= 0.0:
        return 0.0
    focus = cam.focus_distance if cam.focus_distance is not None else scene.gaze.camera_mm
    image = scene.gaze.camera_mm + scene.gaze.screen_mm
    flat = (scene.gaze.camera_mm + scene.gaze.screen_mm) * scene.gaze.pitch_mm / cam.focal
    scale = footprint_mm(scene, direction) / flat
    return cam.focal / cam.f_number * abs(image - focus) / focus * scale


def box_share(footprint: float, periods: np.ndarray, samples: int = 0) -> np.ndarray:
    """The modulation share a box footprint of ``footprint`` mm keeps of fringes of
    ``periods`` (mm): ``|sin x / (n sin(x / n))|``, ``x = π w / p``, for ``n`` samples
    spread evenly over the pixel (the renderer's ``render.supersample``: ``n = 1`` point-
    samples and keeps everything); ``samples = 0``: a real pixel, ``|sin x / x|``."""
    x = math.pi * footprint / np.asarray(periods, np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        if samples:
            share = np.sin(x) / (samples * np.sin(x / samples))
        else:
            share = np.sin(x) / x
    return np.abs(np.where(x == 0.0, 1.0, share))


def disc_share(blur: float, periods: np.ndarray) -> np.ndarray:
    """The share a uniform blur disc of diameter ``blur`` mm keeps: ``|2 J1(x) / x|``,
    ``x = π b / p``."""
    from scipy.special import j1

    x = math.pi * blur / np.asarray(periods, np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        share = 2.0 * j1(x) / x
    return np.abs(np.where(x == 0.0, 1.0, share))


def closed_form_share(
    scene: Any, direction: str, periods: np.ndarray, finish: np.ndarray | None = None
) -> np.ndarray:
    """The chain's closed form at the gaze point: the box footprint as the renderer
    samples it, the lens's blur disc and ``finish``, what the finish's reflection lobe keeps
    of each period (the oracle's ``gaze_share``; None: a mirror's 1), the
    transfer functions multiplied."""
    w = footprint_mm(scene, direction)
    share = box_share(w, periods, scene.render.supersample) * disc_share(
        blur_mm(scene, direction), periods
    )
    return share if finish is None else share * finish


def screen_harmonics(em: FringesTable, count: int = 4096) -> np.ndarray:
    """The displayed fringe's Fourier amplitudes ``b_h`` (h = 0 … count/2; ``b_1`` the
    fundamental a sharp mirror shows), the screen's grey levels, response, black level and
    room light included (:meth:`FringesTable.screen`), in displayed units."""
    theta = 2.0 * np.pi * np.arange(count) / count
    shown = em.screen().displayed(em.offset + em.amplitude * np.cos(theta))
    spectrum = np.fft.rfft(shown) / count
    spectrum[1:] *= 2.0
    return np.asarray(spectrum.real, np.float64)  # an even function: cosines only


def white_fundamental(em: FringesTable) -> float:
    """``b_1`` over the white the screen displays, ``displayed(1)``: a sharp mirror's
    modulation per unit of its response to the white (what a pixel's share divides by)."""
    white = float(em.screen().displayed(np.array(1.0)))
    return float(screen_harmonics(em)[1]) / white


def gamma_error_rad(harmonics: np.ndarray, shifts: int) -> float:
    """The phase error ``N`` steps leave of the screen's harmonics: ``|b_(N+1) -
    b_(N-1)| / b_1`` (the harmonics ``N ± 1`` alias into the phase; docs/pmd.md)."""
    top = len(harmonics) - 1
    plus = harmonics[shifts + 1] if shifts + 1 <= top else 0.0
    return float(abs(plus - harmonics[shifts - 1]) / harmonics[1])


def quantisation_rms_rad(em: FringesTable, share: float, fundamental: float, shifts: int) -> float:
    """The screen's quantisation as a phase error's root mean square over the pixels:
    ``sqrt(2 / N) (q / sqrt 12) / B`` (each frame's rounding taken as uniform over a grey
    step ``q``; the pixels' footprints average it further, so this is an upper
    estimate)."""
    modulation = share * fundamental
    if not em.largest_step():
        return 0.0
    if not modulation > 0.0:
        return math.inf
    return math.sqrt(2.0 / shifts) * em.largest_step() / math.sqrt(12.0) / modulation


def quantisation_error_rad(em: FringesTable, share: float, fundamental: float) -> float:
    """The screen's quantisation bound ``asin(q / B)``, ``q`` its largest displayed grey
    step and ``B = share · b_1`` the pixel's modulation (displayed units): a fixed
    pattern, the same in every capture."""
    q = em.largest_step()
    modulation = share * fundamental
    if not q:
        return 0.0
    return math.asin(min(1.0, q / modulation)) if modulation > 0 else math.pi / 2


# --------------------------------------------------------------------------- resolution
@dataclass(frozen=True)
class Resolved:
    """The finest resolved period of one direction (or of all: the longest of theirs):
    ``period_mm`` (NaN where none), ``status`` (``ok``; ``below_range``: every probed
    period is resolved, the limit is at most the finest probed; ``unresolved``: none
    is) and ``reason``."""

    period_mm: float
    status: str = "ok"
    reason: str = ""


def finest_resolved(periods: np.ndarray, share: np.ndarray, level: float) -> Resolved:
    """The period below which the modulation share first drops under ``level``, coming
    from the coarsest: log-linear between the two probed periods that straddle it."""
    below = np.flatnonzero(~(share >= level))
    if not below.size:
        return Resolved(
            float(periods[0]),
            "below_range",
            f"every probed period keeps a share >= {level:g}: the limit is at most "
            f"{periods[0]:.3g} mm",
        )
    last = int(below[-1])
    if last == len(periods) - 1:
        return Resolved(
            math.nan,
            "unresolved",
            f"even the coarsest probed period, {periods[-1]:.3g} mm, keeps a share of "
            f"{share[-1]:.3g} < {level:g} (a sharper focus or a finer camera resolves more)",
        )
    lo, hi = share[last], share[last + 1]
    t = (level - lo) / (hi - lo) if hi != lo else 1.0
    log_p = math.log(periods[last]) + t * (math.log(periods[last + 1]) - math.log(periods[last]))
    return Resolved(float(math.exp(log_p)))


def round_up(value: float, digits: int = PERIOD_DIGITS) -> float:
    """``value`` rounded up to ``digits`` significant digits."""
    if not (math.isfinite(value) and value > 0.0):
        return value
    scale = 10.0 ** (math.floor(math.log10(value)) - digits + 1)
    return float(round(math.ceil(value / scale - 1e-9) * scale, 12))


def round_near(value: float, digits: int = PERIOD_DIGITS) -> float:
    """``value`` rounded to ``digits`` significant digits."""
    scale = 10.0 ** (math.floor(math.log10(value)) - digits + 1)
    return float(round(round(value / scale) * scale, 12))


# --------------------------------------------------------------------------- unwrapping
@dataclass(frozen=True)
class ErrorBudget:
    """A coding's phase errors at each period (rad, the worst coded direction):
    ``random`` the noise (one σ), ``systematic`` the screen's bounds (quantisation and
    gamma aliasing) at the period's modulation."""

    periods_mm: tuple[float, ...]
    random: tuple[float, ...]
    systematic: tuple[float, ...]

    def margins(self) -> tuple[float, ...]:
        """Per step ``k -> k+1``, the σ of noise the unwrapping tolerates: ``M`` such
        that ``r (M σ_(k+1) + ε_(k+1)) + M σ_k + ε_k = π`` (``r`` the ratio, ``ε`` the
        systematic bounds); infinite where there is no noise and the bounds fit."""
        out = []
        for k in range(len(self.periods_mm) - 1):
            r = self.periods_mm[k + 1] / self.periods_mm[k]
            room = math.pi - r * self.systematic[k + 1] - self.systematic[k]
            noise = r * self.random[k + 1] + self.random[k]
            if room <= 0.0:
                out.append(0.0)
            else:
                out.append(room / noise if noise > 0.0 else math.inf)
        return tuple(out)


def ladder(finest: float, coarsest: float, count: int) -> tuple[float, ...]:
    """``count`` periods from ``finest`` to ``coarsest`` at one ratio, the inner ones
    rounded to :data:`PERIOD_DIGITS` digits."""
    if count == 1:
        return (finest,)
    ratio = (coarsest / finest) ** (1.0 / (count - 1))
    inner = [round_near(finest * ratio**k) for k in range(1, count - 1)]
    return (finest, *inner, coarsest)
