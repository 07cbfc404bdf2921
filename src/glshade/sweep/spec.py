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
[metric]                       # optional: the instrument and its settings
method = "paper"               # paper (MetricSettings: step_mm, threshold, ...) or pmd
step_mm = 0.25                 # (PmdSettings: modulation_share, grid_points, ...)
[output]
images = false                 # best-phase image of every case (PNG; pmd: the first frame)
```

``size`` may also be an axis of the grid. ``method`` defaults to the instrument the base
scene's emitter is measured by (pmd for fringes); with ``pmd`` every case shows the fringe
sequence on its screen (:func:`glshade.measure.single.as_method`). A case is identified by
:func:`case_id`, the hash of its full scene and the instrument's settings: a changed base
scene or setting makes other cases, and a case already measured is never measured again.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path
from typing import Any

from glshade.components.registry import registry
from glshade.errors import GlshadeError, SceneError
from glshade.measure.engine import Case
from glshade.measure.pmd import PMD_VERSION, PmdSettings, check_scene
from glshade.measure.single import METHODS, as_method
from glshade.metrics.visibility import METRIC_VERSION, MetricSettings
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


_TOP_KEYS = ("base", "size", "grid", "metric", "output")
_OUTPUT_KEYS = ("images",)
#: The key of ``[metric]`` that chooses the instrument; the others are its settings.
METHOD_KEY = "method"
#: An instrument's settings: the paper's stripe metric, or phase measuring.
Settings = MetricSettings | PmdSettings


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
        scene = self.base.with_values([(key, value) for key, value in pairs if key != SIZE_KEY])
        return scene.with_size(size) if size is not None else scene

    def cases(self) -> list[GridPoint]:
        """Every case of the grid, first axis outermost."""
        ranges = [range(len(axis.entries)) for axis in self.axes]
        cases = []
        for index in itertools.product(*ranges):
            scene = self.scene(index)
            cases.append(GridPoint(index, Case(case_id(scene, self.settings), scene)))
        return cases

    def swept_values(self, case: GridPoint) -> dict[str, Any]:
        """The row's swept columns: each linked axis's label, then each swept key's value
        in the case's scene."""
        values: dict[str, Any] = {}
        for axis, i in zip(self.axes, case.index, strict=True):
            if axis.linked:
                values[axis.name] = axis.labels[i]
        for key in self.columns:
            if key not in values:
                values[key] = _column_value(case.scene, key)
        return values

    def manifest(self) -> dict:
        """What ties an output directory to this sweep: the glshade version, the instrument
        (``method``) and its version, the base scene and size, the instrument's settings (a
        grid may grow between runs)."""
        from glshade import __version__

        version = (
            {"pmd_version": PMD_VERSION}
            if self.method == "pmd"
            else {"metric_version": METRIC_VERSION}
        )
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


def _column_value(scene: Scene, key: str) -> Any:
    if key == SIZE_KEY:
        return scene.camera.width
    value = scene.value(key)
    return list(value) if isinstance(value, tuple) else value


def method_of(settings: Settings) -> str:
    """The instrument ``settings`` belong to: ``pmd`` or ``paper``."""
    return "pmd" if isinstance(settings, PmdSettings) else "paper"


def case_id(scene: Scene, settings: Settings) -> str:
    """The case's identity: sha256 of its full scene (as a scene file writes it) and the
    instrument's settings and version (phase measuring: also its method); 16 hex digits.
    The paper metric's identity is exactly what it was before PMD existed, so its sweeps
    resume."""
    identity: dict[str, Any]
    if isinstance(settings, PmdSettings):
        identity = {
            "scene": scene.to_dict(),
            "method": "pmd",
            "pmd": asdict(settings),
            "pmd_version": PMD_VERSION,
        }
    else:
        identity = {
            "scene": scene.to_dict(),
            "metric": asdict(settings),
            "metric_version": METRIC_VERSION,
        }
    text = json.dumps(identity, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


# --------------------------------------------------------------------------- reading
def load_spec(path: str | Path, size: int | None = None) -> SweepSpec:
    """Read and validate a sweep file; ``size`` overrides its ``size``. Any problem is a
    :class:`GlshadeError` whose one line names the file and the field."""
    path = Path(path)
    data = read_toml(path, "sweep file")
    return spec_from_dict(data, path.parent, source=str(path), size=size)


def spec_from_dict(
    data: dict, directory: Path = Path("."), source: str = "<sweep>", size: int | None = None
) -> SweepSpec:
    unknown = sorted(set(data) - set(_TOP_KEYS))
    if unknown:
        raise GlshadeError(
            f"{source}: unknown key {unknown[0]!r}; a sweep file has {', '.join(_TOP_KEYS)}"
        )
    base = _base_scene(data.get("base"), directory, source)
    settings = _settings(data.get("metric", {}), source, base)
    base = as_method(base, method_of(settings))
    size = _size(size if size is not None else data.get("size"), f"{source}: size")
    grid = data.get("grid", {})
    if not isinstance(grid, dict) or not grid:
        raise GlshadeError(
            f'{source}: [grid] must hold at least one axis, e.g. "camera.theta_deg" = [85, 45, 5]'
        )
    axes = tuple(_axis(name, value, source) for name, value in grid.items())
    output = data.get("output", {})
    if not isinstance(output, dict) or set(output) - set(_OUTPUT_KEYS):
        raise GlshadeError(f"{source}: [output] may only hold {', '.join(_OUTPUT_KEYS)}")
    images = output.get("images", False)
    if not isinstance(images, bool):
        raise GlshadeError(f"{source}: output.images must be true or false, got {images!r}")
    spec = SweepSpec(base, axes, size, settings, images, source)
    if spec.count > MAX_CASES:
        raise GlshadeError(
            f"{source}: the grid has {spec.count} cases; at most {MAX_CASES} are allowed"
        )
    _check_keys_apart(axes, source)
    for axis in axes:  # every value applies to the base (the others at their first entry)
        for i in range(len(axis.entries)):
            index = tuple(i if other is axis else 0 for other in axes)
            try:
                scene = spec.scene(index)
            except SceneError as exc:
                raise GlshadeError(f"{source}: grid.{axis.name}: {exc}") from None
            _check_case(scene, settings, f"{source}: grid.{axis.name}")
    return spec


def _check_case(scene: Scene, settings: Settings, where: str) -> None:
    """A case its instrument can measure: its emitter measured by the sweep's method, the
    stripes' phase step at most a period, the fringes decodable."""
    method = method_of(settings)
    measured_by = scene.active.emitter.measured_by
    if measured_by != method:
        raise GlshadeError(
            f"{where}: emitter.kind = {scene.emitter.kind!r} is measured by {measured_by}, not "
            f'by this sweep\'s method {method} (set [metric] method = "{measured_by}")'
        )
    if isinstance(settings, PmdSettings):
        try:
            check_scene(scene)
        except GlshadeError as exc:
            raise GlshadeError(f"{where}: {exc}") from None
    else:
        settings.phases(scene.emitter.period)


def _base_scene(base, directory: Path, source: str) -> Scene:
    if base is None:
        return paper_scene()
    if not isinstance(base, str) or not base.strip():
        raise GlshadeError(f"{source}: base must be the path of a scene file, got {base!r}")
    return Scene.load(directory / base)


def _size(value, where: str) -> int | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int):
        raise GlshadeError(f"{where}: must be an integer number of pixels, got {value!r}")
    return registry().param("camera.width").check(value)


def _settings(table, source: str, base: Scene) -> Settings:
    """``[metric]``: ``method`` (default: the instrument the base scene's emitter is
    measured by) and that instrument's settings."""
    if not isinstance(table, dict):
        raise GlshadeError(
            f"{source}: [metric] must be a table: {METHOD_KEY} ({' or '.join(METHODS)}) and "
            "the instrument's settings"
        )
    table = dict(table)
    method = table.pop(METHOD_KEY, None)
    if method is None:
        method = base.active.emitter.measured_by
    elif method not in METHODS:
        raise GlshadeError(
            f"{source}: metric.{METHOD_KEY}: must be one of {', '.join(METHODS)}, got {method!r}"
        )
    kind: type[MetricSettings] | type[PmdSettings] = (
        PmdSettings if method == "pmd" else MetricSettings
    )
    names = [METHOD_KEY, *(f.name for f in fields(kind))]
    unknown = sorted(set(table) - set(names))
    if unknown:
        raise GlshadeError(
            f"{source}: metric.{unknown[0]}: unknown setting of method {method}; allowed: "
            f"{', '.join(names)}"
        )
    if kind is PmdSettings:
        _check_types(PmdSettings, table, source)
    try:
        return kind(**table)
    except GlshadeError as exc:
        raise GlshadeError(f"{source}: metric.{exc}") from None
    except TypeError as exc:
        raise GlshadeError(f"{source}: [metric]: {exc}") from None


#: What a settings field of each annotation accepts from a file, in words.
_TYPES = {
    "float": ((int, float), "a number"),
    "float | None": ((int, float), "a number"),
    "int": ((int,), "an integer"),
    "str": ((str,), "text"),
}


def _check_types(kind: type, table: dict, source: str) -> None:
    """Each value of ``table`` of the type its field of ``kind`` declares (booleans are
    no numbers): one line naming the setting."""
    declared = {f.name: str(f.type) for f in fields(kind)}
    for name, value in table.items():
        allowed, words = _TYPES[declared[name]]
        if isinstance(value, bool) or not isinstance(value, allowed):
            raise GlshadeError(f"{source}: metric.{name}: must be {words}, got {value!r}")


def _axis(name: str, value, source: str) -> Axis:
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
                    (canonical_key(key), _value(canonical_key(key), v, f"{where}[{i}].{key}"))
                    for key, v in entry.items()
                )
            )
            labels.append(str(label))
        if len(set(map(str, labels))) != len(labels):
            raise GlshadeError(f"{where}: the entries' labels must differ")
        return Axis(name, tuple(entries), tuple(labels))
    checked = tuple(_value(name, v, where) for v in _values(value, where, _unit(name)))
    if len({json.dumps(v, default=str) for v in checked}) != len(checked):
        raise GlshadeError(f"{where}: values must not repeat")
    return Axis(name, tuple(((name, v),) for v in checked), checked)


def _unit(key: str) -> str:
    """The unit of a swept key's numbers (``""`` for ``size``, or one not known: its
    values name it when they are checked)."""
    try:
        entry = registry().entry(key)
        return (entry[0] if entry is not None else registry().param(key)).unit
    except SceneError:
        return ""


def _values(value, where: str, unit: str = "") -> list:
    """A list, or a range ``{start, stop, num}`` / ``{start, stop, step}`` (inclusive);
    a range's numbers may carry a unit (``start = "3 um"``)."""
    if isinstance(value, list):
        if not value:
            raise GlshadeError(f"{where}: an empty list sweeps nothing; give at least one value")
        return value
    if isinstance(value, dict):
        keys = set(value)
        if keys not in ({"start", "stop", "num"}, {"start", "stop", "step"}):
            raise GlshadeError(
                f"{where}: a range is {{start, stop, num}} or {{start, stop, step}}, got "
                f"{{{', '.join(sorted(keys))}}}"
            )
        start, stop = (_number(value[k], f"{where}.{k}", unit) for k in ("start", "stop"))
        if "num" in value:
            num = value["num"]
            if isinstance(num, bool) or not isinstance(num, int) or num < 1:
                raise GlshadeError(f"{where}.num: must be an integer >= 1, got {num!r}")
        else:
            step = _number(value["step"], f"{where}.step", unit)
            if step <= 0:
                raise GlshadeError(f"{where}.step: must be > 0, got {step:g}")
            num = math.floor((stop - start) / step + 1e-9) + 1
        if not (start < stop or (start == stop and num == 1)):
            raise GlshadeError(
                f"{where}: an inverted or empty range (start {start:g}, stop {stop:g}); "
                "start must be below stop (list the values to sweep downwards)"
            )
        if num > MAX_CASES:
            raise GlshadeError(f"{where}.num: at most {MAX_CASES}, got {num}")
        if "step" in value:
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


def _value(key: str, value, where: str):
    """A grid value parsed and checked by its parameter's declaration (an unknown key is
    an error naming it)."""
    if key == SIZE_KEY:
        return _size(value, where)
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
