"""The stripe emitter's table: a plane of Gaussian stripes along ``u``, spaced along ``v``,
and the pattern it shows (its radiance, the level a binarisation cuts it at, its mean).

The radiance ``L(v) = Σ_k exp(-(v - phase - k period)² / (2 σ²))``: each stripe peaks at 1
(its neighbours add about 3e-5 at the default width, FWHM = half a period).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from glshade.components.emitter.table import MAX_STRIPE_PERIOD_MM, MIN_PERIOD_MM
from glshade.errors import SceneError
from glshade.params import Control, Table, param, point_param, turn_param

#: FWHM of one stripe = half a period  =>  sigma = period / (4 sqrt(2 ln 2)).
STRIPE_SIGMA_PER_PERIOD = 1.0 / (4.0 * math.sqrt(2.0 * math.log(2.0)))
#: Beyond this many overlapping stripes the Poisson-summed series replaces the sum.
MAX_DIRECT_TERMS = 64
#: Bisection steps of the binarisation's half-width (to the resolution of float64).
HALF_WIDTH_STEPS = 60

#: Half the spacing of float64 numbers, relative: adding less than ``2**-54`` of a number
#: to it leaves it unchanged.
_HALF_ULP = 2.0**-54
#: The largest sag (``|bow_u| + |bow_v| + |twist|``) as a share of the smaller half size.
MAX_SAG_SHARE = 0.1
#: How the screen is placed (``emitter.pose``).
SCREEN_POSES = ("mirrored", "placed")


def silent_beyond(reach: int, scale: float) -> int:
    """The largest ``K <= reach`` such that the stripes ``|k| > K`` cannot change the
    float64 sum of :meth:`StripesTable.radiance` (``w`` in [-1/2, 1/2], ``scale`` the period
    over σ): summed first, the far left ones stay below half a unit of the first kept
    term; added last, the far right ones below half a unit of the total, which holds the
    nearest stripe. Both bounds are exact, so the sum is bit for bit the same."""
    s2 = scale * scale
    nearest_log = -0.5 * s2 * 0.25  # the nearest stripe at the worst w
    for kept in range(1, reach):
        if -0.5 * s2 * (kept + 0.5) ** 2 < -700.0:  # the first kept term must stay normal
            break
        left = math.log(reach - kept) - s2 * kept  # ratio of the skipped left tail to t_-K
        right = math.log(reach - kept) - 0.5 * s2 * (kept + 0.5) ** 2 - nearest_log
        if max(left, right) < math.log(_HALF_ULP) - 1.0:
            return kept
    return reach


def reduced_phase(phase_mm: float, period_mm: float) -> float:
    """The stripes' phase as the shader and the NumPy radiance take it: unchanged within
    one period of 0 (every phase of the metric's sweep), else reduced exactly
    (``math.remainder``, float64) to within half a period: the same stripes. A phase of
    -9.2e18 mm would otherwise swallow ``v`` entirely (float32 keeps 7 digits, float64
    16) and show a blank image."""
    if abs(phase_mm) <= period_mm:
        return phase_mm
    return math.remainder(phase_mm, period_mm)


def check_sag(values: dict[str, Any]) -> None:
    """A low-order sag, small against the screen: ``|bow_u| + |bow_v| + |twist|`` at most
    :data:`MAX_SAG_SHARE` of the smaller half size ``h``: its slope stays below ``2
    MAX_SAG_SHARE`` (``|∇w| <= (2 |bow| + |twist|) / h``), where the hit's Newton steps
    converge (:func:`glshade.components.emitter.plane.sag_distance`)."""
    sag, half = values.get("sag"), values.get("half_size")
    if sag is None or half is None:
        return
    limit = MAX_SAG_SHARE * min(half)
    if sum(abs(c) for c in sag) > limit:
        raise SceneError(
            "emitter.sag",
            f"[bow_u, bow_v, twist] with |bow_u| + |bow_v| + |twist| <= {limit:g} mm "
            f"({MAX_SAG_SHARE:g} of the smaller half size)",
            list(sag),
        )


@dataclass(frozen=True)
class Emitter(Table):
    """The stripe emitter (mm): ``distance`` from the origin, ``period``, ``stripe_sigma``
    (None: FWHM = half a period), ``phase``, ``half_size``.

    ``period = "auto"`` is worked out by the scene that holds the table (the shortest
    period its camera resolves at the gaze point, :mod:`glshade.components.image_scale`):
    the scene keeps the number in ``period`` and the rule in ``period_auto``, so a copy of
    the scene with another elevation works it out again, and a scene file says ``"auto"``.
    """

    table = "emitter"
    table_checks = (check_sag,)

    distance: float = param(
        "emitter.distance", "mm", 256.0, "origin to the emitter's centre", lo=0.0
    )
    period: float = param(
        "emitter.period", "mm", 2.0,
        'stripe spacing along v; "auto": the shortest multiple of 0.25 mm that spans 6 image '
        "rows at the gaze point (the magnification closed form, docs/physics.md), worked "
        "out again whenever the scene changes",
        lo=MIN_PERIOD_MM, hi=MAX_STRIPE_PERIOD_MM, flag="--period", keywords=("auto",),
        control=Control("period", 0.2, 20.0, log=True, fmt="%.2f mm"),
    )  # fmt: skip
    stripe_sigma: float | None = param(
        "emitter.stripe_sigma", "mm", None,
        "Gaussian width of one stripe (unset: FWHM = half a period)", lo=0.0,
        control=Control("stripe_sigma", 0.02, 10.0, log=True, fmt="%.3f mm"),
    )  # fmt: skip
    phase: float = param(
        "emitter.phase", "mm", 0.0, "shift of the stripes along v", flag="--phase",
        control=Control("phase", -1000.0, 1000.0, fmt="%.3f mm"),
    )  # fmt: skip
    half_size: tuple[float, float] = param(
        "emitter.half_size", "mm", (150.0, 150.0), "half extents in u and v", value_type="pair"
    )
    pose: str = param(
        "emitter.pose", "", "mirrored",
        'how the screen is placed: "mirrored" (centred on the camera\'s line of sight '
        "reflected at the point it aims at, emitter.distance from it and facing it: the "
        'paper\'s rig) or "placed" (centred at emitter.centre, facing emitter.look_at, '
        "emitter.up its v direction); emitter.yaw_deg, pitch_deg and roll_deg turn it "
        "further about its own axes (u, v, normal)",
        value_type="choice", choices=SCREEN_POSES, flag="--screen-pose", quiet=True,
    )  # fmt: skip
    centre: tuple[float, float, float] | None = param(
        "emitter.centre", "mm", None,
        'the screen\'s centre in the world frame (emitter.pose = "placed"; unset: the rig\'s '
        "mirror position)",
        value_type="vector", size=3,
    )  # fmt: skip
    look_at: tuple[float, float, float] = point_param(
        "emitter.look_at",
        (0.0, 0.0, 0.0),
        'the point the screen\'s normal aims at (emitter.pose = "placed")',
    )
    up: tuple[float, float, float] = point_param(
        "emitter.up",
        (0.0, 1.0, 0.0),
        'the direction the screen\'s v axis leans to (emitter.pose = "placed"; not along '
        "its normal)",
        unit="",
    )
    yaw_deg: float = turn_param(
        "emitter.yaw_deg",
        "turn of the screen about its own v axis after it is placed (then pitch_deg about "
        "u, roll_deg about its normal; right-handed)",
    )
    pitch_deg: float = turn_param(
        "emitter.pitch_deg",
        "turn of the screen about its own u axis",
    )
    roll_deg: float = turn_param(
        "emitter.roll_deg",
        "turn of the screen about its own normal",
    )
    sag: tuple[float, float, float] = param(
        "emitter.sag", "mm", (0.0, 0.0, 0.0),
        "the screen's shape, a low-order sag [bow_u, bow_v, twist]: its emitting surface is "
        "displaced along its normal (towards the viewer positive) by w(u, v) = bow_u s² + "
        "bow_v t² + twist s t, s = u / half_u, t = v / half_v (so bow_u is the rise at the "
        "u edges over the centre); a screen point (u, v) is its foot on the plane. A cover "
        "glass follows the bent layer, its front face w + glass_thickness above the plane "
        f"(refracted as a flat glass). The three magnitudes add up to at most {MAX_SAG_SHARE:g} "
        "of the smaller half size; [0, 0, 0]: a flat screen",
        value_type="vector", size=3, role="feature", quiet=True,
    )  # fmt: skip
    #: True when ``period`` was worked out from ``"auto"`` by the scene (not a parameter).
    period_auto: bool = field(default=False, compare=True)

    def values(self) -> dict[str, Any]:
        """The parameters as a scene gives them: ``period`` is ``"auto"`` where the scene
        worked it out (so a changed scene works it out again)."""
        values = super().values()
        if values.pop("period_auto"):
            values["period"] = "auto"
        return values

    @property
    def sigma_mm(self) -> float:
        """The stripe's Gaussian width in mm (the default when ``stripe_sigma`` is unset)."""
        if self.stripe_sigma is not None:
            return self.stripe_sigma
        return self.period * STRIPE_SIGMA_PER_PERIOD

    def effective(self, name: str) -> Any:
        return self.sigma_mm if name == "stripe_sigma" else getattr(self, name)

    def clamp(self, name: str, value: Any) -> Any:
        """A stripe no wider than half a period."""
        return min(value, 0.5 * self.period) if name == "stripe_sigma" else value

    # ---------------------------------------------------------------- the pattern
    @property
    def period_mm(self) -> float:
        """The pattern repeats along ``v`` with this period (the metric's phase sweep)."""
        return self.period

    @property
    def phase_mm(self) -> float:
        return reduced_phase(self.phase, self.period)

    @property
    def feature_mm(self) -> float:
        """The finest length over which the radiance changes: the stripe's width."""
        return self.sigma_mm

    def radiance(self, v: np.ndarray, phase_mm: float | None = None) -> np.ndarray:
        """``L(v)`` (float64; NaN propagates) with the stripes shifted by ``phase_mm``
        (default: the table's phase). Every stripe within ``10σ`` of the nearest is summed,
        nearest first on each side (the next adds < exp(-50)); when more than
        :data:`MAX_DIRECT_TERMS` would overlap (``σ > 3.1 period``) the identical Poisson
        form ``(σ sqrt(2π)/period) (1 + 2 Σ_m exp(-2π² σ² m²/period²) cos(2π m x/period))``
        is used instead."""
        period, sigma = self.period, self.sigma_mm
        phase = reduced_phase(self.phase if phase_mm is None else phase_mm, period)
        reach = math.ceil(10.0 * sigma / period) + 1
        if 2 * reach + 1 <= MAX_DIRECT_TERMS:
            w = (np.asarray(v, np.float64) - phase) / period
            w -= np.round(w)
            total = np.zeros(w.shape)
            scale = period / sigma
            kept = silent_beyond(reach, scale)
            for k in range(-kept, kept + 1):
                total += np.exp(-0.5 * ((w - k) * scale) ** 2)
            return total
        x = np.asarray(v, np.float64) - phase
        ratio = sigma / period
        m_max = int(math.ceil(math.sqrt(45.0 / (2.0 * math.pi**2)) / ratio)) + 1  # exp(-45)
        angle = 2.0 * math.pi * x / period
        series = np.ones_like(x)
        for m in range(1, m_max + 1):
            series += 2.0 * math.exp(-2.0 * math.pi**2 * ratio**2 * m * m) * np.cos(m * angle)
        return ratio * math.sqrt(2.0 * math.pi) * series

    def binary_half_width(self, threshold: float) -> float | None:
        """Half-width ``w*`` (mm) of the region ``L > threshold`` around a stripe centre,
        the radiance taken in float32 as a rendered image holds it.

        ``L`` is periodic and even; when it decreases monotonically from a stripe's centre
        to the middle between stripes (true for every stripe narrower than about a third
        of the period), ``L(v) > threshold`` is exactly ``|v - phase - k period| < w*`` for
        the nearest ``k``: a binarisation without evaluating a single exponential. Returns
        None when that does not hold, 0 when no point is above the threshold and
        ``period / 2`` when every point is.
        """
        period = self.period
        grid = np.linspace(0.0, 0.5 * period, 2049)
        level = self.radiance(grid, 0.0).astype(np.float32).astype(np.float64)
        if np.any(np.diff(level) > 1e-12):
            return None
        if level[0] <= threshold:
            return 0.0
        if level[-1] > threshold:
            return 0.5 * period
        lo, hi = 0.0, 0.5 * period
        for _ in range(HALF_WIDTH_STEPS):
            mid = 0.5 * (lo + hi)
            if float(np.float32(self.radiance(np.array([mid]), 0.0)[0])) > threshold:
                lo = mid
            else:
                hi = mid
        return 0.5 * (lo + hi)

    def mean_radiance(self) -> float:
        """The radiance averaged over a period: ``σ √(2π) / P``."""
        return self.sigma_mm * math.sqrt(2.0 * math.pi) / self.period
