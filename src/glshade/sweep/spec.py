"""A sweep file (docs/sweeps.md): a base scene, a grid over dotted scene keys, the metric's
settings and what to write. No GL here: a sweep is planned, validated and split anywhere.

```toml
base = "scene.toml"            # optional (relative to this file); default: the paper's scene
size = 256                     # optional: pixels across, the base camera's field of view
[grid]                         # axes in this order; the cases are their product
"camera.theta_deg" = [85, 65, 45, 25, 5]
"defect.sigma2" = { start = 1.0, stop = 16.0, num = 4 }      # inclusive, start < stop
"camera.azimuth_deg" = { start = 0.0, stop = 90.0, step = 30.0 }
surface = [ { label = "flat", "surface.kind" = "flat" },        # a linked axis: each entry
            { label = "sphere", "surface.kind" = "sphere", "emitter.period" = 10.0 } ]
                                                                # sets several keys
[measure]                      # optional: the instrument and its settings ([metric] too)
method = "paper"               # paper (MetricSettings: step_mm, threshold, ...) or pmd
step_mm = 0.25                 # (PmdSettings: modulation_share, grid_points, ...)
[output]
images = false                 # best-phase image of every case (PNG; pmd: the first frame)
```

``size`` may also be an axis of the grid. ``method`` defaults to the one the base scene
file's own ``[measure]`` names (its settings come first, the sweep's override them key by
key: :mod:`glshade.instruments.table`), else to the instrument the base scene's emitter is
measured by (pmd for fringes); with ``pmd`` every case shows the fringe
sequence on its screen (:func:`glshade.measure.single.as_method`). A case is identified by
:func:`case_id`, the hash of its full scene and the instrument's settings: a changed base
scene or setting makes other cases, and a case already measured is never measured again.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import math
from collections.abc import Iterator, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, overload

from glshade.components.registry import registry
from glshade.errors import GlshadeError, SceneError
from glshade.instruments.base import Case
from glshade.instruments.registry import instrument_for
from glshade.instruments.table import MeasureTable, file_measure_table, measure_table
from glshade.measure.single import as_method
from glshade.metrics.visibility import MetricSettings
from glshade.params import Param, declared_params
from glshade.scene import Scene, paper_scene
from glshade.scene.model import read_toml
from glshade.units import parse_quantity

#: A grid of more cases than this needs ``--yes`` (about an hour of llvmpipe at 256 px).
MAX_CASES_UNCONFIRMED = 5000
#: A grid of more cases than this is refused (the plan itself would not fit in memory).
MAX_CASES = 1_000_000
SIZE_KEY = "size"
#: Other spellings of keys: ``rig.azimuth_deg`` is ``camera.azimuth_deg``
#: (the emitter follows the camera's keys; docs/sweeps.md).
KEY_ALIASES = {"rig.azimuth_deg": "camera.azimuth_deg"}


def canonical_key(key: str) -> str:
    """A key as the scene spells it (an alias replaced)."""
    return KEY_ALIASES.get(key.strip(), key.strip())


_TOP_KEYS = ("base", "size", "grid", "measure", "metric", "output")
_OUTPUT_KEYS = ("images",)
#: The key of ``[metric]`` that chooses the instrument; the others are its settings.
METHOD_KEY = "method"
#: A grid key that sweeps a setting of the instrument (``measure.threshold``).
MEASURE_PREFIX = "measure."
#: An instrument's settings (its :attr:`~glshade.instruments.base.Instrument.settings_type`).
Settings = Any


@dataclass(frozen=True)
class Axis:
    """One axis of the grid: its name (a dotted key, ``size``, or a linked axis's name),
    its entries (each a map of dotted keys to values) and their labels."""

    name: str
    entries: tuple[tuple[tuple[str, Any], ...], ...]
    labels: tuple[Any, ...]

    @property
    def keys(self) -> tuple[str, ...]:
        """The dotted keys this axis sets (in first appearance order)."""
        return tuple(dict.fromkeys(key for entry in self.entries for key, _ in entry))

    @property
    def linked(self) -> bool:
        return self.keys != (self.name,)


@dataclass(frozen=True)
class GridPoint:
    """One point of the grid: its place (an index per axis) and its case (whose key is
    the case id)."""

    index: tuple[int, ...]
    case: Case
    settings: Any = None  # the instrument's settings at this point (measure.* axes)

    @property
    def case_id(self) -> str:
        return str(self.case.key)

    @property
    def scene(self) -> Scene:
        return self.case.scene


@dataclass(frozen=True)
class SweepSpec:
    """A validated sweep: ``base`` scene (as its instrument measures it), ``axes``,
    ``size`` (None: the base's), the instrument's ``settings`` (:class:`MetricSettings`:
    the paper's stripe metric; :class:`PmdSettings`: phase measuring), ``images`` (write
    an image of each case)."""

    base: Scene = field(default_factory=paper_scene)
    axes: tuple[Axis, ...] = ()
    size: int | None = None
    settings: Settings = field(default_factory=MetricSettings)
    images: bool = False
    source: str = "<sweep>"

    @property
    def method(self) -> str:
        """The instrument: ``paper`` or ``pmd``."""
        return method_of(self.settings)

    @property
    def count(self) -> int:
        return math.prod(len(axis.entries) for axis in self.axes)

    @property
    def columns(self) -> tuple[str, ...]:
        """The swept columns of the table: linked axes' names, then every swept key."""
        names = [axis.name for axis in self.axes if axis.linked]
        return tuple(dict.fromkeys([*names, *(key for axis in self.axes for key in axis.keys)]))

    def scene(self, index: tuple[int, ...]) -> Scene:
        """The scene at one point of the grid: the base with every axis's entry applied
        (all at once, so keys that only make sense together can be swept together)."""
        pairs = [pair for axis, i in zip(self.axes, index, strict=True) for pair in axis.entries[i]]
        size = next((value for key, value in reversed(pairs) if key == SIZE_KEY), self.size)
        scene = self.base.with_values(
            [(key, value) for key, value in pairs if key != SIZE_KEY and not _measures(key)]
        )
        return scene.with_size(size) if size is not None else scene

    def settings_at(self, index: tuple[int, ...]) -> Settings:
        """The instrument's settings at one point of the grid: the sweep's, with each
        ``measure.KEY`` axis's value."""
        pairs = [pair for axis, i in zip(self.axes, index, strict=True) for pair in axis.entries[i]]
        changed = {key.removeprefix(MEASURE_PREFIX): v for key, v in pairs if _measures(key)}
        return dataclasses.replace(self.settings, **changed) if changed else self.settings

    def point(self, index: tuple[int, ...]) -> GridPoint:
        """The case at one point of the grid (its scene made and hashed now)."""
        scene, settings = self.scene(index), self.settings_at(index)
        return GridPoint(index, Case(case_id(scene, settings), scene), settings)

    def cases(self) -> GridCases:
        """Every case of the grid, first axis outermost: a sequence that makes each case
        when it is asked for (:class:`GridCases`), never the whole grid at once."""
        return GridCases(self)

    def swept_values(self, case: GridPoint) -> dict[str, Any]:
        """The row's swept columns: each linked axis's label, then each swept key's value
        in the case's scene."""
        values: dict[str, Any] = {}
        for axis, i in zip(self.axes, case.index, strict=True):
            if axis.linked:
                values[axis.name] = axis.labels[i]
        for key in self.columns:
            if key not in values and _measures(key):
                values[key] = getattr(case.settings, key.removeprefix(MEASURE_PREFIX))
            elif key not in values:
                values[key] = _column_value(case.scene, key)
        return values

    def manifest(self) -> dict:
        """What ties an output directory to this sweep: the glshade version, the instrument
        (``method``) and its version, the base scene and size, the instrument's settings (a
        grid may grow between runs)."""
        from glshade import __version__

        chosen = instrument_for(self.settings)
        version = {chosen.version_key: chosen.version}
        return json.loads(
            json.dumps(
                {
                    "glshade_version": __version__,
                    "method": self.method,
                    **version,
                    "base_scene": self.base.to_dict(),
                    "size": self.size,
                    "metric": asdict(self.settings),
                },
                default=str,
            )
        )


class GridCases(Sequence[GridPoint]):
    """The cases of a grid in its order (first axis outermost), each made (its scene
    built, its id hashed: about 2 ms) only when it is asked for: iterating holds one case
    at a time, :meth:`chunks` one chunk, and ``cases[n]`` makes case ``n`` alone. A slice
    is a list of the cases it names."""

    def __init__(self, spec: SweepSpec) -> None:
        self.spec = spec
        self._lengths = tuple(len(axis.entries) for axis in spec.axes)

    def __len__(self) -> int:
        return self.spec.count

    @overload
    def __getitem__(self, n: int) -> GridPoint: ...

    @overload
    def __getitem__(self, n: slice) -> list[GridPoint]: ...

    def __getitem__(self, n: int | slice) -> GridPoint | list[GridPoint]:
        if isinstance(n, slice):
            return [self[i] for i in range(*n.indices(len(self)))]
        if not -len(self) <= n < len(self):
            raise IndexError(f"case {n} of a grid of {len(self)}")
        return self.spec.point(self.place(n % len(self)))

    def __iter__(self) -> Iterator[GridPoint]:
        for index in itertools.product(*(range(length) for length in self._lengths)):
            yield self.spec.point(index)

    def place(self, n: int) -> tuple[int, ...]:
        """The place in the grid (an index per axis) of case number ``n``."""
        place = []
        for length in reversed(self._lengths):
            n, i = divmod(n, length)
            place.append(i)
        return tuple(reversed(place))

    def chunks(self, first: int = 16, most: int = 4096) -> Iterator[list[GridPoint]]:
        """The cases in consecutive lists: ``first`` cases, then twice as many each time
        up to ``most`` (the first case comes soon; later chunks are long enough to share
        each geometry's defect-free analysis and to keep many workers busy)."""
        size, chunk = first, []
        for point in self:
            chunk.append(point)
            if len(chunk) == size:
                yield chunk
                size, chunk = min(2 * size, most), []
        if chunk:
            yield chunk


def _measures(key: str) -> bool:
    """A grid key that sweeps a setting of the instrument, not the scene."""
    return key.startswith(MEASURE_PREFIX)


def _column_value(scene: Scene, key: str) -> Any:
    if key == SIZE_KEY:
        return scene.camera.width
    value = scene.value(key)
    return list(value) if isinstance(value, tuple) else value


def method_of(settings: Settings) -> str:
    """The name of the instrument ``settings`` belong to."""
    return instrument_for(settings).name


def case_id(scene: Scene, settings: Settings) -> str:
    """The case's identity: sha256 of its full scene (as a scene file writes it) and the
    instrument's settings and version (phase measuring: also its method); 16 hex digits.
    The paper metric's identity is exactly what it was before PMD existed, so its sweeps
    resume."""
    identity = {"scene": scene.to_dict(), **instrument_for(settings).identity(settings)}
    text = json.dumps(identity, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


# --------------------------------------------------------------------------- writing
def sweep_toml(data: dict[str, Any]) -> str:
    """A sweep file's text of ``data`` (top-level keys, ``[grid]``, ``[measure]``), each
    axis on one line in the order given (a linked axis as a list of inline tables: the
    order of the axes is the order of the cases, which a TOML writer's tables-last layout
    would change)."""
    lines = [
        f"{_toml_key(k)} = {_toml_value(v)}" for k, v in data.items() if not isinstance(v, dict)
    ]
    for table, values in data.items():
        if isinstance(values, dict):
            lines += ["", f"[{table}]"]
            lines += [f"{_toml_key(k)} = {_toml_value(v)}" for k, v in values.items()]
    return "\n".join(lines) + "\n"


def _toml_key(key: str) -> str:
    """A bare key where TOML allows one (ASCII letters, digits, ``_`` and ``-``), else
    quoted."""
    bare = key.replace("_", "").replace("-", "")
    return key if bare.isascii() and bare.isalnum() else json.dumps(key)


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(float(value)) if isinstance(value, float) else str(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, dict):
        return (
            "{ " + ", ".join(f"{_toml_key(k)} = {_toml_value(v)}" for k, v in value.items()) + " }"
        )
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise TypeError(f"a sweep file holds numbers, text, lists and tables, not {value!r}")


# --------------------------------------------------------------------------- reading
def load_spec(path: str | Path, size: int | None = None, *, yes: bool = True) -> SweepSpec:
    """Read and validate a sweep file; ``size`` overrides its ``size``; ``yes`` False
    refuses a grid beyond :data:`MAX_CASES_UNCONFIRMED` cases (``--yes`` not given). Any
    problem is a :class:`GlshadeError` whose one line names the file and the field."""
    path = Path(path)
    data = read_toml(path, "sweep file")
    return spec_from_dict(data, path.parent, source=str(path), size=size, yes=yes)


def spec_from_dict(
    data: dict,
    directory: Path = Path("."),
    source: str = "<sweep>",
    size: int | None = None,
    *,
    yes: bool = True,
) -> SweepSpec:
    """A validated sweep (:func:`load_spec`). The grid's size is checked first, from its
    axes' lengths alone (no value built, no scene made): beyond :data:`MAX_CASES` cases it
    is refused, beyond :data:`MAX_CASES_UNCONFIRMED` unless ``yes``."""
    unknown = sorted(set(data) - set(_TOP_KEYS))
    if unknown:
        raise GlshadeError(
            f"{source}: unknown key {unknown[0]!r}; a sweep file has {', '.join(_TOP_KEYS)}"
        )
    grid = data.get("grid", {})
    if not isinstance(grid, dict) or not grid:
        raise GlshadeError(
            f'{source}: [grid] must hold at least one axis, e.g. "camera.theta_deg" = [85, 45, 5]'
        )
    check_grid([_axis_length(name, value, source) for name, value in grid.items()], source, yes)
    base, base_table = _base_scene(data.get("base"), directory, source)
    settings = _settings(data, source, base, base_table)
    base = as_method(base, method_of(settings))
    size = _size(size if size is not None else data.get("size"), f"{source}: size")
    axes = tuple(_axis(name, value, source, type(settings)) for name, value in grid.items())
    output = data.get("output", {})
    if not isinstance(output, dict) or set(output) - set(_OUTPUT_KEYS):
        raise GlshadeError(f"{source}: [output] may only hold {', '.join(_OUTPUT_KEYS)}")
    images = output.get("images", False)
    if not isinstance(images, bool):
        raise GlshadeError(f"{source}: output.images must be true or false, got {images!r}")
    spec = SweepSpec(base, axes, size, settings, images, source)
    _check_keys_apart(axes, source)
    for axis in axes:  # every value applies to the base (the others at their first entry)
        for i in range(len(axis.entries)):
            index = tuple(i if other is axis else 0 for other in axes)
            try:
                scene = spec.scene(index)
            except SceneError as exc:
                raise GlshadeError(f"{source}: grid.{axis.name}: {exc}") from None
            _check_case(scene, spec.settings_at(index), f"{source}: grid.{axis.name}")
    return spec


def count_text(lengths: Sequence[int], unit: str = "cases") -> str:
    """How a count of cases arises from its factors: ``99 x 100 x 100 = 990000 cases``
    (a factor repeated more than twice as a power: ``64^4 = 16777216``)."""
    total = math.prod(lengths)
    factors = []
    for length, run in itertools.groupby(lengths):
        times = len(list(run))
        factors += [f"{length}^{times}"] if times > 2 else [str(length)] * times
    shown = " x ".join(factors)
    return f"{total} {unit}" if shown == str(total) else f"{shown} = {total} {unit}"


def check_count(total: int, how: str, yes: bool) -> int:
    """``total`` cases (counted, never listed), or one line that starts with ``how`` (what
    is counted and how it arises, e.g. ``the grid has 99 x 100 x 100 = 990000 cases``):
    beyond :data:`MAX_CASES` it is refused, beyond :data:`MAX_CASES_UNCONFIRMED` unless
    ``yes`` (``--yes``)."""
    if total > MAX_CASES:
        raise GlshadeError(f"{how}; at most {MAX_CASES} are allowed")
    if total > MAX_CASES_UNCONFIRMED and not yes:
        raise GlshadeError(f"{how} (more than {MAX_CASES_UNCONFIRMED}); add --yes to run it")
    return total


def check_grid(lengths: Sequence[int], source: str, yes: bool) -> int:
    """A grid of axes of these lengths (:func:`check_count`)."""
    return check_count(math.prod(lengths), f"{source}: the grid has {count_text(lengths)}", yes)


def _check_case(scene: Scene, settings: Settings, where: str) -> None:
    """A case its instrument can measure: its emitter measured by the sweep's method, the
    stripes' phase step at most a period, the fringes decodable."""
    chosen = instrument_for(settings)
    measured_by = scene.active.emitter.measured_by
    if chosen.prepared(scene) is not scene:  # it would show its own emitter instead
        raise GlshadeError(
            f"{where}: emitter.kind = {scene.emitter.kind!r} is measured by {measured_by}, not "
            f'by this sweep\'s method {chosen.name} (set [measure] method = "{measured_by}")'
        )
    try:
        chosen.check_case(scene, settings)
    except GlshadeError as exc:
        raise GlshadeError(f"{where}: {exc}") from None


def _base_scene(base, directory: Path, source: str) -> tuple[Scene, MeasureTable]:
    """The base scene and its file's ``[measure]`` table (empty for the paper's scene)."""
    if base is None:
        return paper_scene(), MeasureTable()
    if not isinstance(base, str) or not base.strip():
        raise GlshadeError(f"{source}: base must be the path of a scene file, got {base!r}")
    scene = Scene.load(directory / base)
    return scene, file_measure_table(directory / base, scene.active.emitter.measured_by)


def _size(value, where: str) -> int | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int):
        raise GlshadeError(f"{where}: must be an integer number of pixels, got {value!r}")
    return registry().param("camera.width").check(value)


def _settings(data: dict, source: str, base: Scene, base_table: MeasureTable) -> Settings:
    """``[measure]`` (or its older name ``[metric]``): ``method`` (default: the one the
    base scene file's ``[measure]`` names, else the instrument the base scene's emitter is
    measured by) and that instrument's settings, each checked against its declaration,
    over the base file's where they are for the same instrument."""
    if "measure" in data and "metric" in data:
        raise GlshadeError(f"{source}: [measure] and [metric] are one table: give one of them")
    name = "measure" if "measure" in data else "metric"
    default = base_table.method or base.active.emitter.measured_by
    table = measure_table(data.get(name), f"{source}: ", default, name)
    method = table.method or default
    return base_table.settings(method, table.values, f"{source}: ", name)


def _axis(name: str, value, source: str, settings_type: type | None = None) -> Axis:
    """One ``[grid]`` axis; a ``measure.KEY`` axis is checked against ``settings_type``'s
    declarations (the sweep's instrument's settings)."""
    where = f"{source}: grid.{name}"
    name = canonical_key(name)
    if isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
        entries, labels = [], []
        for i, entry in enumerate(value):
            entry = dict(entry)
            label = entry.pop("label", i)
            if not entry:
                raise GlshadeError(f"{where}[{i}]: a linked entry must set at least one dotted key")
            entries.append(
                tuple(
                    (
                        canonical_key(key),
                        _value(canonical_key(key), v, f"{where}[{i}].{key}", settings_type),
                    )
                    for key, v in entry.items()
                )
            )
            labels.append(str(label))
        if len(set(map(str, labels))) != len(labels):
            raise GlshadeError(f"{where}: the entries' labels must differ")
        return Axis(name, tuple(entries), tuple(labels))
    unit = _unit(name, settings_type)
    checked = tuple(_value(name, v, where, settings_type) for v in _values(value, where, unit))
    if len({json.dumps(v, default=str) for v in checked}) != len(checked):
        raise GlshadeError(f"{where}: values must not repeat")
    return Axis(name, tuple(((name, v),) for v in checked), checked)


def _unit(key: str, settings_type: type | None = None) -> str:
    """The unit of a swept key's numbers (``""`` for ``size``, or one not known: its
    values name it when they are checked)."""
    if key.startswith(MEASURE_PREFIX):
        declared = {p.key: p for p in declared_params(settings_type)} if settings_type else {}
        found = declared.get(key.removeprefix(MEASURE_PREFIX))
        return found.unit if found is not None else ""  # an unknown one is named when checked
    try:
        entry = registry().entry(key)
        return (entry[0] if entry is not None else registry().param(key)).unit
    except SceneError:
        return ""


def _axis_length(name: str, value, source: str) -> int:
    """How many entries an axis has, from its list's length or its range's numbers (no
    value is built or checked here but the range's own)."""
    where = f"{source}: grid.{name}"
    if isinstance(value, list):
        if not value:
            raise GlshadeError(f"{where}: an empty list sweeps nothing; give at least one value")
        return len(value)
    if isinstance(value, dict):
        return _range(value, where, _unit(canonical_key(name)))[2]
    return 1


def _range(value: dict, where: str, unit: str) -> tuple[float, float, int, float | None]:
    """A range's ``start``, ``stop``, number of values and ``step`` (None: given by
    ``num``), checked: at most :data:`MAX_CASES` values."""
    keys = set(value)
    if keys not in ({"start", "stop", "num"}, {"start", "stop", "step"}):
        raise GlshadeError(
            f"{where}: a range is {{start, stop, num}} or {{start, stop, step}}, got "
            f"{{{', '.join(sorted(keys))}}}"
        )
    start, stop = (_number(value[k], f"{where}.{k}", unit) for k in ("start", "stop"))
    step = None
    if "num" in value:
        num = value["num"]
        if isinstance(num, bool) or not isinstance(num, int) or num < 1:
            raise GlshadeError(f"{where}.num: must be an integer >= 1, got {num!r}")
    else:
        step = _number(value["step"], f"{where}.step", unit)
        if step <= 0:
            raise GlshadeError(f"{where}.step: must be > 0, got {step:g}")
        steps = (stop - start) / step  # an overflow is inf: refused below, never floored
        num = math.floor(steps + 1e-9) + 1 if math.isfinite(steps) and steps < MAX_CASES else 0
        if not num and stop > start:
            raise GlshadeError(
                f"{where}.step: {step:g} from {start:g} to {stop:g} makes more than "
                f"{MAX_CASES} values"
            )
    if not (start < stop or (start == stop and num == 1)):
        raise GlshadeError(
            f"{where}: an inverted or empty range (start {start:g}, stop {stop:g}); "
            "start must be below stop (list the values to sweep downwards)"
        )
    if num > MAX_CASES:
        raise GlshadeError(f"{where}.num: at most {MAX_CASES}, got {num}")
    return start, stop, num, step


def _values(value, where: str, unit: str = "") -> list:
    """A list, or a range ``{start, stop, num}`` / ``{start, stop, step}`` (inclusive);
    a range's numbers may carry a unit (``start = "3 um"``)."""
    if isinstance(value, list):
        if not value:
            raise GlshadeError(f"{where}: an empty list sweeps nothing; give at least one value")
        return value
    if isinstance(value, dict):
        start, stop, num, step = _range(value, where, unit)
        if step is not None:
            return [start + k * step for k in range(num)]
        return [start] if num == 1 else [start + (stop - start) * k / (num - 1) for k in range(num)]
    return [value]


def _number(value, where: str, unit: str = "") -> float:
    """A range's number: a number in ``unit``, or text with its own unit."""
    if isinstance(value, str):
        try:
            value = parse_quantity(value, unit, where)
        except SceneError as exc:
            raise GlshadeError(str(exc)) from None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise GlshadeError(f"{where}: must be a finite number, got {value!r}")
    return float(value)


def _value(key: str, value, where: str, settings_type: type | None = None):
    """A grid value parsed and checked by its parameter's declaration (an unknown key is
    an error naming it); ``measure.KEY``: by the instrument's setting's."""
    if key == SIZE_KEY:
        return _size(value, where)
    if key.startswith(MEASURE_PREFIX) and settings_type is not None:
        declared = _setting(key, settings_type, where)
        try:
            text = isinstance(value, str) and declared.value_type not in ("choice", "text")
            return declared.check(declared.parse(value) if text else value)
        except SceneError as exc:
            raise GlshadeError(f"{where}: {_without(exc, key)}") from None
    if "." not in key:
        raise GlshadeError(
            f"{where}: unknown key {key!r}; expected a dotted scene key such as camera.theta_deg, "
            "'size', or a list of tables (a linked axis)"
        )
    try:
        entry = registry().entry(key)
        if entry is not None:  # a formula's parameter: one number, checked with its table
            param, name = entry
            number = param.parse_entry(name, value) if isinstance(value, str) else value
            return dict(param.check(((name, number),)))[name]
        param = registry().param(key)
        if isinstance(value, str) and param.value_type not in ("choice", "text", "path"):
            value = param.parse(value)
        if param.value_type in ("real", "integer", "choice", "pair", "vector"):
            return param.check(value, registry().choices(param))
        return value
    except SceneError as exc:
        raise GlshadeError(f"{where}: {_without(exc, key)}") from None


def _setting(key: str, settings_type: type, where: str) -> Param:
    """The declaration of setting ``measure.KEY`` of ``settings_type`` (one line naming
    the settings there are otherwise)."""
    declared = {p.key: p for p in declared_params(settings_type)}
    found = declared.get(key.removeprefix(MEASURE_PREFIX))
    if found is None:
        names = ", ".join(MEASURE_PREFIX + name for name in declared)
        raise GlshadeError(
            f"{where}: not a setting of this sweep's instrument; its settings: {names}"
        )
    return found


def _without(exc: SceneError, key: str) -> str:
    """The error's text, without its field where ``where`` already names it."""
    text = str(exc)
    return text.removeprefix(f"{key}: ")


def _check_keys_apart(axes: tuple[Axis, ...], source: str) -> None:
    """No key is set by two axes, nor a whole table by one and an entry of it by another."""
    seen: dict[str, str] = {}
    for axis in axes:
        for key in axis.keys:
            if key in seen:
                raise GlshadeError(
                    f"{source}: {key} is set by two axes ({seen[key]} and {axis.name})"
                )
            seen[key] = axis.name
    for key, name in seen.items():
        whole = ".".join(key.split(".")[:2])
        if whole != key and seen.get(whole, name) != name:
            raise GlshadeError(
                f"{source}: {key} and {whole} are set by two axes ({name} and {seen[whole]})"
            )
