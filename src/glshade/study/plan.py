"""What the paper's study sweeps (the paper's Table 1): the grid of cases, what a case is
and its key.
No GL here: plans are made, validated and split anywhere (a Dask client included)."""

from __future__ import annotations

import functools
import math
from dataclasses import asdict, dataclass, field
from itertools import pairwise
from pathlib import Path
from typing import Any

from glshade.components.camera.perspective.table import MIN_THETA_DEG
from glshade.errors import GlshadeError
from glshade.metrics import visibility as vis
from glshade.metrics.visibility import METRIC_VERSION
from glshade.scene import PAPER_SURFACES, Camera, Scene, paper_scene

PAPER_THETAS = (85.0, 75.0, 65.0, 55.0, 45.0, 35.0, 25.0, 15.0, 5.0)
PAPER_SIGMA2S = (1.0, 4.0, 9.0, 16.0)
PAPER_DMAXS = (0.003, 0.005)
#: θ columns of the paper's image grids (Figs. 10, 11, 14, 15, 18, 19).
GRID_THETAS = (85.0, 45.0, 5.0)
#: Side of the thumbnails kept for the grids, pixels.
THUMBNAIL = 256
#: Cases drawn as the Fig. 9 contour overlay, when they are part of the plan: the paper's
#: default scene, and a steep dent at a grazing view whose stripe map folds.
OVERLAY_CASES = {
    ("flat", 45.0, 4.0, 0.005): "fig09_contour_overlay.png",
    ("flat", 5.0, 1.0, 0.005): "fig09_contour_overlay_fold.png",
}

#: A study of more cases than this needs ``--yes`` (the sweep's limit: about an hour of
#: llvmpipe at 256 px).
MAX_CASES_UNCONFIRMED = 5000
#: A study of more cases than this is refused: a run holds every case's scene and row in
#: memory (about 2 KiB a case: 200 MiB here; a million would be the whole memory budget).
MAX_STUDY_CASES = 100_000
#: Most σ² of a study: its image grids draw a row of thumbnails for each (about 18 MiB of
#: memory a row: 1.3 GiB at 64).
MAX_SIGMA2S = 64

#: The instrument whose settings a plan carries (:attr:`StudyPlan.metric`): every study
#: measures the stripe study's cases, and phase measuring reads the stripe study beside it.
PLAN_METHOD = "paper"

#: A point of the plan: (surface, θ in degrees, σ² in mm², dmax in mm).
PlanPoint = tuple[str, float, float, float]


def case_key(surface: str, theta: float, sigma2: float, dmax: float) -> str:
    """A case's key: the file stem of its case files (dmax in µm, as the file names of
    the figures)."""
    return f"{surface_label(surface)}_theta{theta:g}_sigma2_{sigma2:g}_dmax{dmax * 1000:g}um"


def is_scene_file(surface: str) -> bool:
    """A study's surface is one of the paper's kinds or a scene file (a free-form
    surface: a height map or a formula, paper eq. 3)."""
    return surface.lower().endswith(".toml")


def surface_label(surface: str) -> str:
    """The name a surface's files and figures carry: its kind, or its scene file's stem."""
    return Path(surface).stem if is_scene_file(surface) else surface


def case_scene(
    surface: str, theta: float = 45.0, sigma2: float = 4.0, dmax: float = 0.005
) -> Scene:
    """The scene of one case: the paper's for its surfaces; for a scene file, the file's
    scene (its surface, camera and emitter) with θ, σ² and dmax of the case."""
    if is_scene_file(surface):
        path = Path(surface)
        stamp = path.stat().st_mtime_ns if path.is_file() else 0
        base = _scene_file(str(path.resolve()), stamp)
        return base.updated(camera={"theta_deg": theta}, defect={"sigma2": sigma2, "dmax": dmax})
    return paper_scene(surface, theta, sigma2, dmax)


@functools.lru_cache(maxsize=16)
def _scene_file(path: str, stamp: int) -> Scene:
    return Scene.load(path)


def check_size(plan: StudyPlan, yes: bool) -> None:
    """A study of more than :data:`MAX_CASES_UNCONFIRMED` cases runs only when confirmed
    (``--yes``); one line says how its count arises."""
    if plan.count > MAX_CASES_UNCONFIRMED and not yes:
        raise GlshadeError(
            f"{plan.count_text()} (more than {MAX_CASES_UNCONFIRMED}); add --yes to run it"
        )


def _shown(values: tuple[float, ...], most: int = 12) -> str:
    """A list of numbers as a line shows it: a long one by its first values."""
    shown = ", ".join(f"{v:g}" for v in values[:most])
    return shown if len(values) <= most else f"{shown}, … ({len(values)} values)"


def _float_list(
    name: str, values, lo: float, hi: float, closed_hi: bool = False
) -> tuple[float, ...]:
    values = tuple(float(v) for v in values)
    if not values:
        raise GlshadeError(f"{name}: must list at least one value")
    for v in values:
        inside = lo < v <= hi if closed_hi else lo < v < hi
        if not (math.isfinite(v) and inside):
            bracket = "]" if closed_hi else ")"
            raise GlshadeError(
                f"{name}: every value must be in ({lo:g}, {hi:g}{bracket}, got {v:g}"
            )
    seen: set[float] = set()
    for v in values:
        if v in seen:
            raise GlshadeError(
                f"{name}: values must not repeat, got {v:g} twice in {_shown(values)}"
            )
        seen.add(v)
    return values


@dataclass(frozen=True)
class StudyPlan:
    """What to sweep: Table 1 by default, at ``size`` pixels across (paper: 1024)."""

    surfaces: tuple[str, ...] = PAPER_SURFACES
    thetas: tuple[float, ...] = PAPER_THETAS
    sigma2s: tuple[float, ...] = PAPER_SIGMA2S
    dmaxs: tuple[float, ...] = PAPER_DMAXS
    size: int = 1024
    metric: vis.MetricSettings = field(default_factory=vis.MetricSettings)

    def __post_init__(self) -> None:
        if not self.surfaces:
            raise GlshadeError("surfaces: must list at least one of " + ", ".join(PAPER_SURFACES))
        for s in self.surfaces:
            if s not in PAPER_SURFACES and not is_scene_file(s):
                raise GlshadeError(
                    f"surfaces: unknown surface {s!r}; allowed: {', '.join(PAPER_SURFACES)} or a "
                    "scene file (.toml) of a free-form surface"
                )
        if len({surface_label(s) for s in self.surfaces}) != len(self.surfaces):
            raise GlshadeError("surfaces: must not repeat (scene files by their names)")
        thetas = _float_list("thetas", self.thetas, MIN_THETA_DEG, 90.0)
        if any(a <= b for a, b in pairwise(thetas)):
            raise GlshadeError(
                "thetas: must be strictly decreasing, from high to low viewpoints as in the paper "
                f"(85 … 5), got {_shown(thetas)}"
            )
        object.__setattr__(self, "thetas", thetas)
        object.__setattr__(self, "sigma2s", _float_list("sigma2s", self.sigma2s, 0.0, math.inf))
        object.__setattr__(self, "dmaxs", _float_list("dmaxs", self.dmaxs, 0.0, math.inf))
        if len(self.sigma2s) > MAX_SIGMA2S:
            raise GlshadeError(
                f"sigma2s: at most {MAX_SIGMA2S} values (the image grids draw a row for each), "
                f"got {len(self.sigma2s)}"
            )
        if self.count > MAX_STUDY_CASES:  # before any scene is made
            raise GlshadeError(f"{self.count_text()}; at most {MAX_STUDY_CASES} are allowed")
        Camera().resampled(self.size)  # validates the size
        for surface in self.surfaces:
            if is_scene_file(surface):
                case_scene(surface)  # the file loads: its errors name it
            self.metric.phases(
                self.scene(surface, self.thetas[0], self.sigma2s[0], self.dmaxs[0]).emitter.period
            )

    @property
    def count(self) -> int:
        """The plan's number of cases (counted, not listed)."""
        return len(self.surfaces) * len(self.thetas) * len(self.sigma2s) * len(self.dmaxs)

    def count_text(self) -> str:
        """How the number of cases arises, in one line naming the flags."""
        lists = (
            (self.surfaces, "surfaces"),
            (self.thetas, "thetas"),
            (self.sigma2s, "sigma2s"),
            (self.dmaxs, "dmaxs"),
        )
        factors = " x ".join(f"{len(values)} {name}" for values, name in lists)
        return f"--surfaces/--thetas/--sigma2s/--dmaxs: {factors} = {self.count} cases"

    def scene(self, surface: str, theta: float, sigma2: float, dmax: float) -> Scene:
        return case_scene(surface, theta, sigma2, dmax).with_size(self.size)

    def cases(self) -> list[PlanPoint]:
        return [
            (s, t, v, d)
            for s in self.surfaces
            for t in self.thetas
            for v in self.sigma2s
            for d in self.dmaxs
        ]

    def sweep_grid(self) -> dict[str, Any]:
        """The plan as a sweep file's ``[grid]`` (docs/sweeps.md) over the paper's scene:
        a linked ``surface`` axis (each surface with the paper's stripe period for it),
        then θ, σ² and dmax, in the study's order, so the sweep's cases are the plan's.
        A scene file's surface has no such entry (its case is its file's scene): refused
        in one line."""
        from glshade.scene.paper import PAPER_PERIOD_MM

        files = [s for s in self.surfaces if is_scene_file(s)]
        if files:
            raise GlshadeError(
                f"--as-sweep: {files[0]}: a scene file's cases are its own scene's (sweep "
                "them with base = that file); only the paper's surfaces have a sweep form"
            )
        default_period = paper_scene().emitter.period
        surfaces = [
            {
                "label": s,
                "surface.kind": s,
                "emitter.period": PAPER_PERIOD_MM.get(s, default_period),
            }
            for s in self.surfaces
        ]
        return {
            "surface": surfaces,
            "camera.theta_deg": list(self.thetas),
            "defect.sigma2": list(self.sigma2s),
            "defect.dmax": list(self.dmaxs),
        }

    def to_dict(self) -> dict:
        data = asdict(self)
        data["surfaces"] = list(self.surfaces)
        data["metric_version"] = METRIC_VERSION
        return data
