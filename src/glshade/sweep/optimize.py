"""Where should the camera be? The viewpoint that maximises a dent's visibility, or the
worst-case visibility over a family of dents (``glshade optimize``, docs/sweeps.md).

1. **Coarse grid** over the ``--over`` keys (their bounds), every point measured for every
   member of the family, on the sweep machinery (in-process or on Dask: the grid's cases
   go in batches of :data:`CHUNK_CASES`). How many cases a search may measure at most is
   checked before any is made (:func:`check_cases`).
2. **Bounded refinement** from the best grid point with SciPy's Nelder–Mead inside the
   grid cell around it (± one grid step per key, clipped to the bounds), initial simplex
   half a step wide, at most ``refine_evaluations`` points.

The objective at a point is the worst case over the family (the minimum of the members'
visibilities). ``--metric`` chooses it (:func:`glshade.sweep.goals.goals`): the paper's
metric or its continuous limit, or a number a phase-measuring station reads (``pmd_snr``,
``pmd_shift_mm``, ``pmd_depth_um``, ``pmd_slope_urad`` maximised; ``pmd_noise_mm``
minimised, its worst case the largest); a pmd metric measures every scene as the station
does (the fringe sequence on the scene's screen). A case whose number cannot be read (its
status) makes its point unusable.

The paper's metric is piecewise constant (whole pixels): a gradient method would see zero
slope almost everywhere. Nelder–Mead only ranks points, so it works on plateaus, and ties
are broken by the continuous visibility, which every case computes anyway: the score is
``visibility_px + TIE · visibility_continuous_px`` (``TIE = 1e-3`` keeps the order of
whole pixels for any continuous value under 1000 px). The refinement never returns worse
than the grid: the optimum is the best point evaluated.
**Flatness**: the near-optimal set is every evaluated point within ``tolerance`` of the
optimum (paper metric: 0, the points of the optimum's whole-pixel plateau; the others: 5 %);
per key, the range of those points tells how far the camera may move without losing more
than that.
"""

from __future__ import annotations

import itertools
import math
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from glshade.components.registry import registry
from glshade.errors import GlshadeError, SceneError
from glshade.instruments.base import Case, Goal
from glshade.instruments.record import Record
from glshade.instruments.registry import instrument
from glshade.measure.single import as_method
from glshade.scene import Scene
from glshade.sweep.goals import goal_of, unit, unreadable, words
from glshade.sweep.spec import Settings, canonical_key, case_id, check_count, count_text
from glshade.units import QuantityError, examples, parse_quantity

#: Tie-break weight of the continuous visibility in the paper metric's score.
TIE = 1e-3
#: Bounds of keys an engineer sweeps most, when ``--over`` gives none (the paper's θ range).
DEFAULT_BOUNDS = {"camera.theta_deg": (5.0, 85.0), "camera.azimuth_deg": (0.0, 180.0)}
#: Grid points per key by the number of keys (``--grid`` overrides).
GRID_POINTS = {1: 9, 2: 7}
GRID_POINTS_MANY = 5
MAX_GRID_POINTS = 10_000


@dataclass(frozen=True)
class Dimension:
    """One key the optimiser moves, within ``[lo, hi]`` (in the key's unit)."""

    key: str
    lo: float
    hi: float
    label: str | None = None  # the spelling the user gave (``rig.azimuth_deg``), if not ``key``

    @property
    def name(self) -> str:
        return self.label or self.key


@dataclass(frozen=True)
class OptimizeResult:
    """The optimum (a value per key), its objective (``value``: the chosen metric, worst
    case over the family, in :attr:`unit`), the near-optimal ranges (within ``tolerance``
    of it, the same unit), and every evaluated point (``points``: (n, k) array,
    ``values``: (n,) objective; the first ``grid_count`` are the coarse grid)."""

    dimensions: tuple[Dimension, ...]
    optimum: dict[str, float]
    value: float
    metric: str
    tolerance: float
    near_optimal: dict[str, tuple[float, float]]
    points: np.ndarray
    values: np.ndarray
    grid_shape: tuple[int, ...]
    grid_count: int
    cases: int = 0
    unmeasurable: int = 0  # cases whose number could not be read (their points excluded)
    members: list[dict[str, float]] = field(default_factory=list)
    member_values: np.ndarray | None = None  # (n, members): each member's value
    unmeasurable_statuses: dict[str, int] = field(default_factory=dict)

    @property
    def goal(self) -> Goal:
        return goal_of(self.metric)

    @property
    def unit(self) -> str:
        return unit(self.goal)

    @property
    def visibility_px(self) -> float:
        """The objective's value under the paper metrics' name."""
        return self.value

    def near_text(self) -> str:
        """What the near-optimal set is, in words."""
        if self.tolerance == 0.0:
            return "on the optimum's whole-pixel plateau"
        return f"within {self.tolerance:g}{f' {self.unit}' if self.unit else ''} of the optimum"

    @property
    def evaluations(self) -> int:
        return len(self.values)

    def summary(self) -> dict:
        """``glshade optimize --json``: the paper metrics' value as ``visibility_px``
        (tolerance ``tolerance_px``), a phase-measuring one under its column's name; every
        metric's also as ``value`` (in ``unit``)."""
        goal = self.goal
        key = goal.value_key or goal.column
        value = self.value if goal.digits is None else round(self.value, goal.digits)
        named = {key: value}
        tolerance = {goal.tolerance_key: self.tolerance}
        return {
            "optimum": self.optimum,
            **named,
            "value": value,
            "unit": self.unit,
            "metric": self.metric,
            "maximised": goal.sense > 0,
            "evaluations": self.evaluations,
            "grid_evaluations": self.grid_count,
            "cases": self.cases,
            "unmeasurable_cases": self.unmeasurable,
            "unmeasurable_statuses": self.unmeasurable_statuses,
            "family_members": len(self.members) or 1,
            "near_optimal": {key: list(span) for key, span in self.near_optimal.items()},
            **tolerance,
        }


# --------------------------------------------------------------------------- parsing
def parse_over(text: str) -> tuple[Dimension, ...]:
    """``KEY[=LO..HI][,KEY[=LO..HI]]``: the keys to move and their bounds."""
    dims = []
    for item in _items(text, "--over"):
        given, _, span = item.partition("=")
        key = canonical_key(given)
        unit = _numeric_unit(key, "--over")
        if span:
            lo, hi = _span(span, f"--over {key}", unit=unit)
        elif key in DEFAULT_BOUNDS:
            lo, hi = DEFAULT_BOUNDS[key]
        else:
            raise GlshadeError(f"--over {key}: give its bounds, e.g. {key}=LO..HI")
        dims.append(Dimension(key, lo, hi, given.strip() if given.strip() != key else None))
    if len({d.key for d in dims}) != len(dims):  # two spellings of one key count as one
        raise GlshadeError("--over: a key is listed twice")
    return tuple(dims)


#: A family of dents as its axes: each key and its values (the members: every combination).
FamilyAxes = tuple[tuple[str, tuple[float, ...]], ...]


def parse_family(text: str | None, points: int = 3) -> list[dict[str, float]]:
    """``KEY=LO..HI`` (``points`` values, ends included) or ``KEY=V1|V2|...``, comma
    separated: the family's members are every combination ([{}] without a family)."""
    return family_members(parse_family_axes(text, points))


def parse_family_axes(text: str | None, points: int = 3) -> FamilyAxes:
    """The axes of ``--family`` (:func:`parse_family`): how many members it has is the
    product of their lengths, known before any member is made (:func:`check_cases`)."""
    if not text:
        return ()
    axes: list[tuple[str, tuple[float, ...]]] = []
    for item in _items(text, "--family"):
        key, sep, span = item.partition("=")
        key = canonical_key(key)
        if not sep:
            raise GlshadeError(f"--family {item!r}: expected KEY=LO..HI or KEY=V1|V2")
        unit = _numeric_unit(key, "--family")
        if "|" in span:
            values = [_float(v, f"--family {key}", unit) for v in span.split("|")]
            if len(set(values)) != len(values):
                shown = "|".join(f"{v:g}" for v in values)
                raise GlshadeError(f"--family {key}: values must not repeat, got {shown}")
        else:
            lo, hi = _span(span, f"--family {key}", allow_equal=True, unit=unit)
            values = [lo] if lo == hi else [float(v) for v in np.linspace(lo, hi, points)]
        axes.append((key, tuple(values)))
    if len({k for k, _ in axes}) != len(axes):
        raise GlshadeError("--family: a key is listed twice")
    return tuple(axes)


def family_members(axes: FamilyAxes) -> list[dict[str, float]]:
    """Every combination of the family's axes ([{}]: no family)."""
    keys = [key for key, _ in axes]
    return [
        dict(zip(keys, combo, strict=True))
        for combo in itertools.product(*(values for _, values in axes))
    ]


def check_cases(
    dimensions: Sequence[Dimension],
    family: FamilyAxes,
    grid_points: int | None,
    refine_evaluations: int,
    yes: bool,
) -> int:
    """The most cases a search measures (every viewpoint of the grid and of the
    refinement, times every member of the family), counted from the lengths alone, or one
    line saying how the count arises: refused beyond :data:`~glshade.sweep.spec.MAX_CASES`,
    and beyond :data:`~glshade.sweep.spec.MAX_CASES_UNCONFIRMED` unless ``yes``."""
    per_key = grid_size(dimensions, grid_points)
    grid = per_key ** len(dimensions)
    viewpoints = grid + refine_evaluations
    lengths = [len(values) for _, values in family]
    members = math.prod(lengths)
    how = f"{viewpoints} viewpoints ({grid} on the grid + at most {refine_evaluations} refining)"
    if family:
        how = f"{count_text(lengths, 'dents per viewpoint')} x {how}"
    total = members * viewpoints
    return check_count(total, f"--family/--over: {how} = {total} cases", yes)


def _items(text: str, flag: str) -> list[str]:
    items = [item.strip() for item in text.split(",") if item.strip()]
    if not items:
        raise GlshadeError(f"{flag}: expected at least one dotted key")
    return items


def _numeric_unit(key: str, flag: str) -> str:
    """The unit of a numeric key (a real or integer parameter, or a formula's parameter,
    ``surface.parameters.a``); any other key is an error naming the flag."""
    try:
        entry = registry().entry(key)
        param = entry[0] if entry is not None else registry().param(key)
    except SceneError as exc:
        raise GlshadeError(f"{flag}: {exc}") from None
    if entry is None and param.value_type not in ("real", "integer"):
        raise GlshadeError(
            f"{flag} {key}: not a number ({param.value_type}); sweep it with glshade sweep instead"
        )
    return param.unit


def _span(text: str, where: str, allow_equal: bool = False, unit: str = "") -> tuple[float, float]:
    """``LO..HI``: each end a number in ``unit``, or with its own (``3um..8um``)."""
    lo_text, sep, hi_text = text.partition("..")
    if not sep:
        raise GlshadeError(f"{where}: expected a range LO..HI, got {text!r}")
    lo, hi = _float(lo_text, where, unit), _float(hi_text, where, unit)
    if not (lo < hi or (allow_equal and lo == hi)):
        raise GlshadeError(
            f"{where}: an empty or inverted range {lo:g}..{hi:g}; LO must be below HI"
        )
    return lo, hi


def _float(text: str, where: str, unit: str = "") -> float:
    try:
        value = parse_quantity(text, unit, where)
    except QuantityError:
        raise
    except SceneError:
        shown = examples(unit) if unit else "a number"
        raise GlshadeError(f"{where}: expected {shown}, got {text.strip()!r}") from None
    if not math.isfinite(value):
        raise GlshadeError(f"{where}: expected a finite number, got {text.strip()!r}")
    return value


# --------------------------------------------------------------------------- the search
def grid_size(dimensions: Sequence[Dimension], points: int | None = None) -> int:
    """Grid points per key: ``points``, or the default for this many keys; at least 2,
    at most :data:`MAX_GRID_POINTS` in all."""
    n = points or GRID_POINTS.get(len(dimensions), GRID_POINTS_MANY)
    if n < 2:
        raise GlshadeError(f"--grid: at least 2 points per key, got {n}")
    if n ** len(dimensions) > MAX_GRID_POINTS:
        raise GlshadeError(
            f"--grid: {n}^{len(dimensions)} points is more than {MAX_GRID_POINTS}; use fewer"
        )
    return n


def grid_axes(dimensions: Sequence[Dimension], points: int | None = None) -> list[np.ndarray]:
    n = grid_size(dimensions, points)
    return [np.linspace(d.lo, d.hi, n) for d in dimensions]


#: ``objective(points (n, k)) -> (scores (n,), values (n,), member values (n, m))``.
Objective = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]


def search(
    objective: Objective,
    dimensions: Sequence[Dimension],
    *,
    grid_points: int | None = None,
    refine_evaluations: int = 30,
    tolerance_px: float | None = None,
    metric: str = "continuous",
    members: list[dict[str, float]] | None = None,
) -> OptimizeResult:
    """Maximise ``objective``'s score over the box of ``dimensions``: coarse grid, then
    bounded Nelder–Mead in the best grid cell (module doc). ``objective`` is called with a
    batch of points (the whole grid at once, so it may distribute it). ``metric`` names the
    values (:func:`glshade.sweep.goals.goals`): whether less of them is better, and the
    near-optimal set's
    tolerance (``tolerance_px``, in their unit; default: 0 for the paper metric's whole
    pixels, 5 % of the optimum's value for the others)."""
    from scipy.optimize import minimize

    axes = grid_axes(dimensions, grid_points)
    grid = np.array(list(itertools.product(*axes)), dtype=np.float64)
    scores, values, member_values = objective(grid)
    evaluated = _Evaluated([grid], [scores], [values], [member_values])
    best = grid[int(np.argmax(scores))]
    steps = np.array([a[1] - a[0] for a in axes])
    if refine_evaluations > 0 and np.isfinite(np.max(scores)):  # nothing to refine from
        cell = _grid_cell(best, steps, dimensions)
        start = _Start(best, float(np.max(scores)), steps)
        _refine(objective, evaluated, start, cell, refine_evaluations, minimize)
    return _search_result(
        evaluated,
        dimensions,
        grid_shape=tuple(len(a) for a in axes),
        grid_count=len(grid),
        metric=metric,
        tolerance_px=tolerance_px,
        members=members,
    )


@dataclass
class _Evaluated:
    """Every batch of points the search has evaluated, in order (the grid first), with
    the objective's scores, values and members' values of each batch."""

    points: list[np.ndarray]
    scores: list[np.ndarray]
    values: list[np.ndarray]
    members: list[np.ndarray]

    def add(
        self, points: np.ndarray, scores: np.ndarray, values: np.ndarray, members: np.ndarray
    ) -> None:
        """Record one more batch."""
        self.points.append(points)
        self.scores.append(scores)
        self.values.append(values)
        self.members.append(members)


@dataclass(frozen=True)
class _Start:
    """Where the refinement starts: the best grid point, its score, and the grid's step
    per key."""

    point: np.ndarray
    score: float
    steps: np.ndarray


def _grid_cell(
    best: np.ndarray, steps: np.ndarray, dimensions: Sequence[Dimension]
) -> tuple[np.ndarray, np.ndarray]:
    """The box the refinement stays in: one grid step either side of ``best`` per key,
    clipped to the bounds of ``dimensions`` (its low and high corners)."""
    lows, highs = np.array([d.lo for d in dimensions]), np.array([d.hi for d in dimensions])
    return np.maximum(best - steps, lows), np.minimum(best + steps, highs)


def _refine(
    objective: Objective,
    evaluated: _Evaluated,
    start: _Start,
    cell: tuple[np.ndarray, np.ndarray],
    budget: int,
    minimize: Callable,
) -> None:
    """Bounded Nelder–Mead from ``start`` inside ``cell``, at most ``budget`` evaluations,
    the initial simplex half a grid step wide; every new point (rounded to 1e-9) is
    evaluated once and recorded in ``evaluated``."""
    cell_lo, cell_hi = cell
    seen: dict[tuple, float] = {}

    def negative(x: np.ndarray) -> float:
        x = np.clip(x, cell_lo, cell_hi)
        key = tuple(np.round(x, 9))
        if key not in seen:
            s, v, m = objective(x[None, :])
            evaluated.add(x[None, :], s, v, m)
            seen[key] = float(s[0])
        return -seen[key]

    best, steps = start.point, start.steps
    simplex = np.vstack(
        [best] + [np.clip(best + 0.5 * steps * e, cell_lo, cell_hi) for e in np.eye(len(best))]
    )
    seen[tuple(np.round(best, 9))] = start.score
    minimize(
        negative,
        best,
        method="Nelder-Mead",
        bounds=list(zip(cell_lo, cell_hi, strict=True)),
        options={
            "initial_simplex": simplex,
            "maxfev": budget,
            "xatol": 1e-3 * steps.min(),
            "fatol": 1e-4,
        },
    )


def _near_tolerance(tolerance_px: float | None, metric: str, optimum_value: float) -> float:
    """How far from the optimum's value a point is near-optimal: ``tolerance_px`` when
    given, else 0 for the paper metric's whole pixels and 5 % of the optimum's value for
    the others."""
    if tolerance_px is not None:
        return tolerance_px
    return 0.0 if goal_of(metric).whole else 0.05 * max(abs(optimum_value), 1e-9)


def _near_points(
    points: np.ndarray, values: np.ndarray, winner: int, sense: int, tolerance: float, keys: int
) -> np.ndarray:
    """The evaluated points within ``tolerance`` of the winner's value (in the sense of
    the metric); one row of NaN when none (no point could be read)."""
    near = points[sense * values >= sense * values[winner] - tolerance]
    if not len(near):  # no point could be read: the caller says so
        near = points[:0].reshape(0, keys)
        near = np.vstack([near, np.full((1, keys), np.nan)])
    return near


def _search_result(
    evaluated: _Evaluated,
    dimensions: Sequence[Dimension],
    *,
    grid_shape: tuple[int, ...],
    grid_count: int,
    metric: str,
    tolerance_px: float | None,
    members: list[dict[str, float]] | None,
) -> OptimizeResult:
    """The search's result from every evaluated point: the optimum is the best score, the
    near-optimal ranges span the points within the tolerance of its value."""
    points_all = np.vstack(evaluated.points)
    scores_all, values_all = np.concatenate(evaluated.scores), np.concatenate(evaluated.values)
    winner = int(np.argmax(scores_all))
    sense = goal_of(metric).sense
    tolerance = _near_tolerance(tolerance_px, metric, values_all[winner])
    near = _near_points(points_all, values_all, winner, sense, tolerance, len(dimensions))
    return OptimizeResult(
        dimensions=tuple(dimensions),
        optimum={d.name: round(float(points_all[winner, i]), 4) for i, d in enumerate(dimensions)},
        value=float(values_all[winner]),
        metric=metric,
        tolerance=float(f"{tolerance:.4g}"),
        near_optimal={
            d.name: (round(float(near[:, i].min()), 4), round(float(near[:, i].max()), 4))
            for i, d in enumerate(dimensions)
        },
        points=points_all,
        values=values_all,
        grid_shape=grid_shape,
        grid_count=grid_count,
        members=members or [],
        member_values=np.vstack(evaluated.members),
    )


# --------------------------------------------------------------------------- scenes
def settings_for(metric: str, settings: Settings | None = None) -> Settings:
    """The instrument's settings of ``metric``: ``settings`` when they are that
    instrument's, its defaults when None."""
    kind = instrument(goal_of(metric).method).settings_type
    if settings is None:
        return kind()
    if not isinstance(settings, kind):
        raise GlshadeError(
            f"settings: --metric {metric} is measured with {kind.__name__}, got "
            f"{type(settings).__name__}"
        )
    return settings


#: Cases measured per call to the executor: the objective holds at most this many scenes.
CHUNK_CASES = 4096


class SceneObjective:
    """The worst case of ``metric`` over a family, measured by an executor (in-process or
    Dask: :func:`glshade.measure.where.open_executor`); every case measured once (by
    id), the points' cases in chunks of :data:`CHUNK_CASES`, and of each case only its
    numbers kept. A phase-measuring metric measures each scene as a station does (its
    screen shows the fringe sequence)."""

    def __init__(
        self,
        base: Scene,
        dimensions: Sequence[Dimension],
        family: list[dict[str, float]],
        settings: Settings,
        metric: str,
        executor,
    ) -> None:
        self.goal = goal_of(metric)
        settings = settings_for(metric, settings)
        self.base = as_method(base, self.goal.method)
        self.dimensions, self.family = tuple(dimensions), family
        self.settings, self.metric, self.executor = settings, metric, executor
        #: Case id -> the objective's number and the tie-break's (NaN: none), and whether
        #: the number can be read.
        self.numbers: dict[str, tuple[float, float, bool]] = {}
        #: Case id -> why its number cannot be read (status: reason).
        self.unreadable: dict[str, str] = {}
        for point in (tuple(d.lo for d in dimensions), tuple(d.hi for d in dimensions)):
            for member in _each_value(family):  # valid scenes before any work
                self._check(self.scene(point, member))

    def _check(self, scene: Scene) -> None:
        """A scene the objective's instrument can measure, one line otherwise."""
        instrument(self.goal.method).check_case(scene, self.settings)
        if self.goal.needs_sensor and not scene.active.records(scene):
            raise GlshadeError(
                f"--metric {self.metric}: needs a sensor (without one the decoded points carry "
                "no noise: pmd_noise_mm is 0 and pmd_snr unbounded); give one, e.g. --set "
                "sensor.full_well_e=10000"
            )

    def scene(self, point: Sequence[float], member: dict[str, float]) -> Scene:
        pairs = [*zip((d.key for d in self.dimensions), point, strict=True), *member.items()]
        try:
            return self.base.with_values([(key, float(value)) for key, value in pairs])
        except SceneError as exc:
            raise GlshadeError(f"--over/--family: a bound gives no valid scene: {exc}") from None

    def __call__(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        shape = (len(points), len(self.family))
        chosen, tie = np.full(shape, np.nan), np.zeros(shape)
        readable = np.zeros(shape, bool)
        pairs = itertools.product(range(shape[0]), range(shape[1]))
        while chunk := list(itertools.islice(pairs, CHUNK_CASES)):
            ids = self._measured([(tuple(points[i]), self.family[j]) for i, j in chunk])
            for (i, j), key in zip(chunk, ids, strict=True):
                chosen[i, j], tie[i, j], readable[i, j] = self.numbers[key]
        goal = self.goal
        if goal.tie_column is not None:  # whole units, ties broken by the tie column
            score = chosen + TIE * tie
        else:
            score = goal.sense * chosen
        # a point is only as good as its worst member, and a member whose number cannot be
        # read makes the point unusable: never the optimum, never near it
        usable = readable.all(axis=1)
        with np.errstate(invalid="ignore"):  # unusable points' NaNs are replaced
            worst = np.where(usable, score.min(axis=1), -np.inf)
            value = np.where(usable, goal.sense * (goal.sense * chosen).min(axis=1), np.nan)
        return worst, value, chosen

    def _measured(self, cases: list[tuple[Sequence[float], dict[str, float]]]) -> list[str]:
        """The ids of ``cases`` (a point and a member each), those not yet measured
        measured now."""
        scenes = [self.scene(point, member) for point, member in cases]
        ids = [case_id(scene, self.settings) for scene in scenes]
        todo = {i: Case(i, s) for i, s in zip(ids, scenes, strict=True) if i not in self.numbers}
        for key, record, _ in self.executor.rows(list(todo.values()), self.settings, False):
            self.numbers[key] = self._kept(key, record)
        return ids

    def _kept(self, key: str, record: Record) -> tuple[float, float, bool]:
        """What the objective keeps of a case's record: its number, the tie-break's, and
        whether the number can be read (if not, why is kept in :attr:`unreadable`)."""
        number = _number(getattr(record, self.goal.column))
        tie = 0.0
        if self.goal.tie_column is not None:
            tie = _number(getattr(record, self.goal.tie_column))
        if unreadable(self.goal, record.status):
            self.unreadable[key] = f"{record.status}: {record.status_reason}"
            return number, tie, False
        if not math.isfinite(number):
            self.unreadable[key] = f"{record.status}: {self.goal.column} has no value"
            return number, tie, False
        return number, tie, True

    @property
    def cases(self) -> int:
        return len(self.numbers)


def _each_value(family: list[dict[str, float]]) -> list[dict[str, float]]:
    """Members that give every value of every key of the family once: the first member
    with one value changed (of a family of every combination, each of its values)."""
    if not family or not family[0]:
        return family[:1]
    first = family[0]
    values = {(key, value) for member in family for key, value in member.items()}
    changed = [{**first, key: value} for key, value in sorted(values) if first.get(key) != value]
    return [first, *changed]


def _number(value) -> float:
    return math.nan if value is None else float(value)


def optimize_scene(
    base: Scene,
    dimensions: Sequence[Dimension],
    family: list[dict[str, float]],
    *,
    metric: str = "paper",
    settings: Settings | None = None,
    executor,
    grid_points: int | None = None,
    refine_evaluations: int = 30,
) -> OptimizeResult:
    """The viewpoint search on a real scene (module doc); ``settings``: the instrument's
    of ``metric`` (None: its defaults)."""
    settings = settings_for(metric, settings)
    objective = SceneObjective(base, dimensions, family, settings, metric, executor)
    result = search(
        objective,
        dimensions,
        grid_points=grid_points,
        refine_evaluations=refine_evaluations,
        metric=metric,
        members=family if family != [{}] else [],
    )
    if not math.isfinite(result.value):
        why = next(iter(objective.unreadable.values()), "")
        raise GlshadeError(
            f"optimize: no point of the search could be measured ({len(objective.unreadable)} "
            f"of {objective.cases} cases not measurable; first: {why})"
        )
    statuses = Counter(why.partition(":")[0] for why in objective.unreadable.values())
    return replace(
        result,
        cases=objective.cases,
        unmeasurable=len(objective.unreadable),
        unmeasurable_statuses=dict(statuses),
    )


# --------------------------------------------------------------------------- figure
def objective_figure(result: OptimizeResult, path: Path, title: str = "") -> None:
    """The objective over the coarse grid: a curve (one key; each family member faint),
    a map (two keys), or a curve per key through the best grid point (more)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from glshade.files import atomic_write_bytes

    dims = result.dimensions
    worst = "worst-case " if result.members else ""
    ylabel = f"{worst}{words(result.goal)}"
    if len(dims) == 2:
        fig, ax = plt.subplots(figsize=(6.4, 5.0))
        _draw_objective_map(fig, ax, result, ylabel)
    else:
        fig, axes = plt.subplots(
            1, len(dims), figsize=(6.4 * min(len(dims), 3), 4.4), squeeze=False
        )
        _draw_objective_curves(axes[0], result, worst, ylabel)
        axes[0][0].legend(loc="best", fontsize=8)
    where = ", ".join(f"{key} = {value:g}" for key, value in result.optimum.items())
    fig.suptitle(
        title or f"optimum {where}\n{worst}{words(result.goal)}: {result.value:.4g}",
        fontsize=10,
    )
    fig.tight_layout()
    import io

    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110)
    plt.close(fig)
    atomic_write_bytes(Path(path), buffer.getvalue(), "--plot")


def _draw_objective_map(fig, ax, result: OptimizeResult, ylabel: str) -> None:
    """Two keys: the grid's values as a colour map (the second key across, the first up),
    the refinement's points, the optimum, and the grid points not measurable."""
    dims, n = result.dimensions, result.grid_count
    grid, values = result.points[:n], result.values[:n]
    shape = result.grid_shape
    mesh = ax.pcolormesh(
        grid[:, 1].reshape(shape),
        grid[:, 0].reshape(shape),
        values.reshape(shape),
        shading="nearest",
        cmap="viridis",
    )
    fig.colorbar(mesh, ax=ax, label=ylabel)
    ax.plot(
        result.points[n:, 1], result.points[n:, 0], ".", color="white", ms=3, label="refinement"
    )
    ax.plot(
        result.optimum[dims[1].name],
        result.optimum[dims[0].name],
        "*",
        color="red",
        ms=14,
        label="optimum",
    )
    lost = ~np.isfinite(values)
    if lost.any():
        ax.plot(grid[lost, 1], grid[lost, 0], "x", color="0.4", ms=6, label="not measurable")
    ax.set_xlabel(dims[1].name)
    ax.set_ylabel(dims[0].name)
    ax.legend(loc="upper left", bbox_to_anchor=(1.25, 1.0), fontsize=8)


def _draw_objective_curves(axes, result: OptimizeResult, worst: str, ylabel: str) -> None:
    """One key or more than two: on each of ``axes`` (one per key) the grid's values along
    that key through the best grid point."""
    n = result.grid_count
    grid, values = result.points[:n], result.values[:n]
    best = grid[int(np.nanargmax(values))]
    for i, ax in enumerate(axes):
        on_line, order = _grid_line(grid, best, i)
        _draw_objective_curve(ax, result, i, on_line, order, worst, ylabel)


def _grid_line(grid: np.ndarray, best: np.ndarray, i: int) -> tuple[np.ndarray, np.ndarray]:
    """The grid points on the line through ``best`` along key ``i`` (a mask of ``grid``'s
    rows) and their order along that key."""
    on_line = np.all(np.isclose(np.delete(grid, i, axis=1), np.delete(best, i)), axis=1)
    return on_line, np.argsort(grid[on_line, i])


def _draw_objective_curve(
    ax, result: OptimizeResult, i: int, on_line, order, worst: str, ylabel: str
) -> None:
    """Key ``i``'s curve of the grid points ``on_line`` (in ``order``): each family
    member faint, the worst case, the points not measurable on the axis, the refinement
    (one key), the near-optimal span and the optimum."""
    n, dim = result.grid_count, result.dimensions[i]
    grid, values = result.points[:n], result.values[:n]
    x = grid[on_line, i][order]
    if result.member_values is not None and len(result.members) > 1:
        for j, _member in enumerate(result.members):
            ax.plot(
                x,
                result.member_values[:n][on_line][order, j],
                color="0.75",
                lw=0.8,
                label="family members" if j == 0 else None,
            )
    shown = values[on_line][order]
    ax.plot(x, shown, "o-", color="C0", label=f"{worst}{result.goal.column}")
    lost = ~np.isfinite(shown)
    if lost.any():  # unreadable viewpoints: marked on the axis, never a number
        ax.plot(
            x[lost], np.zeros(lost.sum()), "x", color="0.4", ms=7, clip_on=False,
            label="not measurable",
        )  # fmt: skip
    if len(result.dimensions) == 1:
        ax.plot(result.points[n:, 0], result.values[n:], "x", color="C1", label="refinement")
    ax.axvspan(*result.near_optimal[dim.name], color="C2", alpha=0.15, label=result.near_text())
    ax.axvline(result.optimum[dim.name], color="C3", lw=1.0, label="optimum")
    ax.set_xlabel(dim.name)
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)
