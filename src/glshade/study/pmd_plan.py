"""What the paper's study runs under phase-measuring deflectometry (``glshade paper --method
pmd``): Table 1's cases (:class:`~glshade.study.plan.StudyPlan`), each scene shown the
fringe sequence on the paper's screen instead of its stripes, recorded through a stated
imaging chain (:class:`PmdChain`: a sensor and the pixels' footprints) and decoded as a
station decodes it (:class:`~glshade.instruments.pmd.settings.PmdSettings`).
No GL here: plans are made and validated anywhere."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field

from glshade.errors import GlshadeError
from glshade.instruments.pmd.settings import PmdSettings
from glshade.measure.single import as_method
from glshade.metrics.physics import base_curvatures
from glshade.scene import Scene
from glshade.study.plan import PlanPoint, StudyPlan, surface_label

#: The shortest finest period of a coding, mm: the paper's stripe spacing.
MIN_FINEST_MM = 2.0
#: Image pixels a finest fringe period spans at least, at the gaze point, at every θ of
#: the plan, by the closed form of the screen's scale (:func:`screen_mm_per_pixel`). A
#: pixel integrating a sinusoid of 3 pixels a period keeps sinc(1/3) = 83 % of its
#: modulation (the paper's metric, which binarises, needs 4).
PERIOD_PX = 3.0
#: Each period is this many times the one before it, up to the first that spans the
#: screen (the unwrapping tolerates a phase error of about π / 8).
PERIOD_RATIO = 8.0
#: The share of a sharp mirror's modulation a pixel's every fringe must keep for the
#: study's station to trust it (the decoding's default is 0.1). Below it the pixel's
#: footprint spans more than about one and a half periods of the finest fringe: its phase
#: is a mix of fringes, not a noisy reading of one. On the sphere at grazing views the
#: screen's far edge is compressed to a few rows, and such pixels decode about half a
#: fringe off and make the noise floor a whole fringe.
MODULATION_SHARE = 0.3
#: The manifest's version of the PMD study's numbers: raised when a change to the chain
#: or the decoding changes them, so a rerun never mixes old cases with new ones.
PMD_STUDY_VERSION = 3


def screen_mm_per_pixel(scene: Scene) -> float:
    """The most screen (mm) one image pixel sees at the gaze point, along its rows or its
    columns: a flat mirror shows ``(Dc + De) δ``; a base of second derivative ``κ_t``
    along the plane of incidence scales the rows by ``m_t = 1 - 2 κ_t Dc De / ((Dc + De)
    sin θ)`` (docs/physics.md), one of ``κ_s`` across it the columns by ``m_s = 1 - 2 κ_s
    sin θ Dc De / (Dc + De)`` (a mirror's sagittal focal length at incidence 90° - θ is
    ``1 / (2 κ_s sin θ)``). NaN where neither has a finite positive value."""
    cam = scene.camera
    dc, de = cam.distance, scene.emitter.distance
    lever = 2.0 * dc * de / (dc + de)
    sine = math.sin(cam.theta_rad)
    tangential, sagittal = base_curvatures(scene)
    scales = [1.0 - lever * tangential / sine, 1.0 - lever * sagittal * sine]
    scales = [m for m in scales if math.isfinite(m) and m > 0.0]
    if not scales:
        return math.nan
    return (dc + de) * cam.pixel_pitch / cam.focal * max(scales)


def finest_period_mm(scenes: list[Scene], period_px: float = PERIOD_PX) -> float:
    """The finest period of a surface's coding: the shortest whole millimetre, at least
    :data:`MIN_FINEST_MM`, that spans ``period_px`` pixels at the gaze point in every one
    of ``scenes`` (the plan's θ on that surface). On the paper's camera (1024²) that is
    2 mm on the flat plate and the cylinder, and 10 mm on the sphere, whose magnification
    m = 35 at θ 5° makes one row see 3.0 mm of the screen: the paper's own 10 mm."""
    scale = [screen_mm_per_pixel(scene) for scene in scenes]
    needed = max((s for s in scale if math.isfinite(s)), default=0.0) * period_px
    return max(MIN_FINEST_MM, float(math.ceil(needed - 1e-9)))


def coding_periods(finest_mm: float, extent_mm: float, ratio: float = PERIOD_RATIO) -> tuple:
    """``finest, finest·ratio, …`` up to the first period at least ``extent_mm`` (the
    screen's length along a coded direction: one fringe then spans the screen)."""
    periods = [float(finest_mm)]
    while periods[-1] < extent_mm:
        periods.append(periods[-1] * ratio)
    return tuple(periods)


@dataclass(frozen=True)
class PmdChain:
    """The imaging chain and the coding of the study's PMD station.

    A sensor of ``full_well_e`` electrons (at the exposure's full scale), ``read_noise_e``
    electrons rms, ``bit_depth`` bits, noise drawn from ``seed``; ``supersample`` ² rays
    per pixel, so each pixel integrates its footprint on the screen (modulation falls
    where the map compresses the fringes); ``shifts`` phase steps per period, both
    directions coded. ``periods``: the coding of every surface (``()``: the plan works it out,
    :meth:`PmdStudyPlan.coding`); ``surface_periods``: the coding of named surfaces."""

    full_well_e: float = 10000.0
    read_noise_e: float = 5.0
    bit_depth: int = 12
    seed: int = 0
    supersample: int = 2
    shifts: int = 4
    periods: tuple[float, ...] = ()
    surface_periods: tuple[tuple[str, tuple[float, ...]], ...] = field(default=())

    def __post_init__(self) -> None:
        object.__setattr__(self, "periods", tuple(float(p) for p in self.periods))
        object.__setattr__(
            self,
            "surface_periods",
            tuple((str(s), tuple(float(p) for p in ps)) for s, ps in self.surface_periods),
        )

    def coding(self, surface: str) -> tuple[float, ...] | None:
        """The periods the chain sets for ``surface`` (None: the plan works them out)."""
        named = dict(self.surface_periods)
        return named.get(surface_label(surface)) or self.periods or None

    def apply(self, scene: Scene, periods: tuple[float, ...]) -> Scene:
        """``scene`` as the station sees it: the fringes of ``periods`` on its screen, the
        sensor and the supersampling."""
        return as_method(scene, "pmd").updated(
            emitter={"periods": list(periods), "shifts": self.shifts},
            sensor={
                "full_well_e": self.full_well_e,
                "read_noise_e": self.read_noise_e,
                "bit_depth": self.bit_depth,
                "seed": self.seed,
            },
            render={"supersample": self.supersample},
        )

    def to_dict(self) -> dict:
        data = asdict(self)
        data["periods"] = list(self.periods)
        data["surface_periods"] = {s: list(ps) for s, ps in self.surface_periods}
        return data


@dataclass(frozen=True)
class PmdStudyPlan:
    """Table 1 (``cases``: its surfaces, θ, σ², dmax and image size) measured by a PMD
    station with ``chain`` and decoded with ``settings``."""

    cases_plan: StudyPlan = field(default_factory=StudyPlan)
    chain: PmdChain = field(default_factory=PmdChain)
    settings: PmdSettings = field(
        default_factory=lambda: PmdSettings(modulation_share=MODULATION_SHARE)
    )
    #: Each surface's fringe periods (mm, finest first), by its label: worked out here.
    codings: tuple[tuple[str, tuple[float, ...]], ...] = field(init=False, default=())

    def __post_init__(self) -> None:
        codings = []
        for surface in self.surfaces:
            try:
                codings.append((surface_label(surface), self._coding(surface)))
            except GlshadeError as exc:
                raise GlshadeError(f"{surface_label(surface)}: {exc}") from None
        object.__setattr__(self, "codings", tuple(codings))
        for surface in self.surfaces:  # every surface's coding is one its screen decodes
            try:
                self.scene(surface, self.thetas[0], self.sigma2s[0], self.dmaxs[0])
            except GlshadeError as exc:
                raise GlshadeError(f"{surface_label(surface)}: {exc}") from None

    def _coding(self, surface: str) -> tuple[float, ...]:
        """The chain's periods where it sets them, else :func:`finest_period_mm` over the
        plan's θ and every :data:`PERIOD_RATIO` times it up to the first that spans the
        screen."""
        given = self.chain.coding(surface)
        if given is not None:
            return given
        scenes = [self.cases_plan.scene(surface, t, 1.0, 0.0) for t in self.thetas]
        screen = as_method(scenes[0], "pmd").emitter
        extent = 2.0 * max(screen.half_size)
        return coding_periods(finest_period_mm(scenes), extent)

    def coding(self, surface: str) -> tuple[float, ...]:
        """The fringe periods (mm, finest first) shown on ``surface``."""
        return dict(self.codings)[surface_label(surface)]

    @property
    def surfaces(self) -> tuple[str, ...]:
        return self.cases_plan.surfaces

    @property
    def thetas(self) -> tuple[float, ...]:
        return self.cases_plan.thetas

    @property
    def sigma2s(self) -> tuple[float, ...]:
        return self.cases_plan.sigma2s

    @property
    def dmaxs(self) -> tuple[float, ...]:
        return self.cases_plan.dmaxs

    @property
    def size(self) -> int:
        return self.cases_plan.size

    def scene(self, surface: str, theta: float, sigma2: float, dmax: float) -> Scene:
        """One case's scene as the station measures it."""
        scene = self.cases_plan.scene(surface, theta, sigma2, dmax)
        return self.chain.apply(scene, self.coding(surface))

    def cases(self) -> list[PlanPoint]:
        return self.cases_plan.cases()

    def to_dict(self) -> dict:
        """The manifest (``pmd_study.json``): the cases, the chain, the decoding."""
        plan = self.cases_plan
        return {
            "surfaces": list(plan.surfaces),
            "thetas": list(plan.thetas),
            "sigma2s": list(plan.sigma2s),
            "dmaxs": list(plan.dmaxs),
            "size": plan.size,
            "chain": self.chain.to_dict(),
            "codings": {label: list(periods) for label, periods in self.codings},
            "settings": asdict(self.settings),
            "pmd_study_version": PMD_STUDY_VERSION,
        }
