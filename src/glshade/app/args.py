"""What the command line's parsers share: one-line usage errors, the scene flags (a short
flag for each parameter that declares one, ``--set PATH=VALUE`` for any), the metric's
flags, typed values with units, and the scene a command line describes."""

from __future__ import annotations

import argparse
import contextlib
import difflib
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

from glshade.components.registry import registry
from glshade.errors import GlshadeError, SceneError, printable
from glshade.params import Param
from glshade.scene import Scene
from glshade.units import QuantityError

if TYPE_CHECKING:
    from glshade.instruments.table import MeasureTable

EXIT_USAGE = 2


class Parser(argparse.ArgumentParser):
    """argparse that reports a usage error as one line (exit 2), like every other error."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(EXIT_USAGE, f"glshade: error: {one_line(message)} (see '{self.prog} --help')\n")


def add_scene_flags(p: argparse.ArgumentParser, device: bool = True) -> None:
    """The scene file and the flags that override it (render and measure): a short flag
    for each parameter that declares one, ``--set PATH=VALUE`` for any parameter;
    ``device``: ``--device`` too (a command that renders)."""
    p.add_argument("scene", nargs="?", type=path_arg, help="scene file (TOML)")
    for param in registry().params():
        if param.flag is not None:
            p.add_argument(param.flag, dest=flag_dest(param), **flag_options(param))
    p.add_argument(
        "--set",
        dest="settings",
        action="append",
        default=[],
        metavar="PATH=VALUE",
        help="set any scene parameter by its dotted path, e.g. --set camera.theta_deg=15, or "
        "by its short name, --set theta=15 (see docs/scene-format.md); applied after the "
        "short flags",
    )
    p.add_argument("--size", type=int, metavar="N", help=SIZE_HELP)
    add_save_scene(p)
    if device:
        add_run_flags(p, ("device",))


def add_run_flags(
    p: argparse.ArgumentParser | argparse._ArgumentGroup,
    keys: Sequence[str],
    defaults: dict[str, Any] | None = None,
    notes: dict[str, str] | None = None,
    words: dict[str, tuple[str, ...]] | None = None,
) -> None:
    """The flags of the run settings ``keys`` (:class:`~glshade.run_settings.
    RunSettings`), their help from the declarations; ``defaults``: a command's own default
    where it differs from the declaration's, ``notes``: what a setting means in this
    command, after its declared meaning, ``words``: the keywords this command takes for a
    setting besides its values (``glshade paper --workers auto``; ``p`` must then be the
    parser). :func:`check_run_settings` checks what was typed."""
    from dataclasses import replace

    if words:
        cast(argparse.ArgumentParser, p).set_defaults(run_words=words)
    declared = _run_params(words)
    for key in keys:
        item = declared[key]
        default = (defaults or {}).get(key, item.default)
        shown = replace(item, default=default).default_text()
        unit = f" {item.unit}" if item.unit else ""
        note = f"; {notes[key]}" if notes and key in notes else ""
        p.add_argument(
            str(item.flag),
            dest=key,
            default=default,
            metavar=key.upper() if item.value_type == "text" else "N",
            help=f"{item.doc}{note} ({item.path}; default {shown}{unit})",
        )


def check_run_settings(args: argparse.Namespace) -> None:
    """Every run setting the command has, as typed, parsed and checked against its
    declaration in place (with the keywords the command takes: :func:`add_run_flags`); a
    bad value is one line naming its flag."""
    for key, item in _run_params(getattr(args, "run_words", None)).items():
        value = getattr(args, key, None)
        if value is None or not isinstance(value, str):
            continue
        try:
            setattr(args, key, item.check(item.parse(value)))
        except (SceneError, QuantityError):
            allowed = item.allowed()
            raise GlshadeError(f"{item.flag}: must be {allowed}, got {value.strip()}") from None


def _run_params(words: dict[str, tuple[str, ...]] | None = None) -> dict[str, Param]:
    """The run settings' declarations by key, each with a command's ``words``."""
    from dataclasses import replace

    from glshade.params import declared_params
    from glshade.run_settings import RunSettings

    found = {item.key: item for item in declared_params(RunSettings)}
    for key, keywords in (words or {}).items():
        found[key] = replace(found[key], keywords=keywords)
    return found


#: ``--size``'s help, for every command that has it.
SIZE_HELP = (
    "N pixels across: the scene file's field of view is kept (its pixel pitch rescaled), "
    "but a camera value typed on the command line (--set camera.pixel_pitch=..., "
    "camera.height) is kept as typed and the field of view follows; --set camera.width "
    "other than N is refused as a conflict"
)


def path_arg(text: str) -> Path:
    """argparse type of a path: an empty one is refused (``Path("")`` would silently be
    the current directory)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("expected a path, got an empty string")
    return Path(text)


def add_save_scene(p: argparse.ArgumentParser) -> None:
    """``--save-scene SCENE.toml``: every command that takes a scene can write the scene it
    actually used (loading the file back gives the same scene)."""
    p.add_argument(
        "--save-scene",
        type=path_arg,
        metavar="SCENE.toml",
        help="also write the scene actually used, as TOML (reads back to the same scene)",
    )


def check_save_scene(args: argparse.Namespace, scene: Scene | None = None) -> None:
    """Refuse a bad ``--save-scene`` path before any work (one of the run's inputs among
    them: :func:`run_inputs`)."""
    check_outputs(args, scene, [])


def run_inputs(args: argparse.Namespace, scene: Scene | None = None) -> tuple[Path, ...]:
    """The files a command line reads: its scene file and the files its scene reads (a
    height map). No output may be one of them."""
    found = [args.scene] if getattr(args, "scene", None) is not None else []
    return (*found, *(scene.input_files() if scene is not None else ()))


#: An output a command line names: its flag, its path, the extensions allowed (empty:
#: any).
Output = tuple[str, Any, tuple[str, ...]]


def check_outputs(args: argparse.Namespace, scene: Scene | None, outputs: Sequence[Output]) -> None:
    """Every output a command names, checked before any work (:func:`glshade.files.
    check_output`: a regular file in a writable directory, proven by a probe, never one of
    the run's inputs), and no two of them the same file. ``--save-scene`` is checked with
    them where the command has it."""
    from glshade.files import check_output

    if getattr(args, "save_scene", None) is not None:
        outputs = [*outputs, ("--save-scene", args.save_scene, (".toml",))]
    inputs = run_inputs(args, scene)
    seen: dict[Path, str] = {}
    for flag, path, suffixes in outputs:
        target = check_output(path, flag, suffixes, inputs=inputs)
        if target in seen:
            raise GlshadeError(f"{flag} {path}: is also {seen[target]}'s output; name two files")
        seen[target] = flag


def save_scene(args: argparse.Namespace, scene: Scene) -> None:
    """Write ``--save-scene`` (after the command's work succeeded: nothing half-way)."""
    if getattr(args, "save_scene", None) is not None:
        scene.save(args.save_scene)


def flag_dest(param: Param) -> str:
    """The argparse destination of a parameter's short flag."""
    return "flag_" + (param.flag or param.path).lstrip("-").replace("-", "_").replace(".", "_")


#: A value with its unit, as a flag's help shows one, by the parameter's unit.
_FLAG_EXAMPLES = {"mm": "5um", "µm": "550nm", "mm²": "4e6um2", "deg": "0.26rad"}


def flag_options(param: Param) -> dict[str, Any]:
    """argparse options of a parameter's short flag, from its declaration."""
    example = _FLAG_EXAMPLES.get(param.unit)
    unit = (
        f" ({param.unit}, or a value with its unit: {example})"
        if example is not None
        else (f" ({param.unit})" if param.unit else "")
    )
    options: dict[str, Any] = {"help": f"{param.path}: {param.doc}{unit}"}
    if param.value_type == "choice":
        options["choices"] = registry().choices(param) or param.choices
    elif param.value_type == "integer":
        options.update(type=param_type(param), metavar="N")
    elif param.value_type == "real":
        options.update(
            type=param_type(param),
            metavar=(param.unit or "X").replace("µ", "u").upper().replace("²", "2"),
        )
    elif param.value_type in ("pair", "vector"):
        count = 2 if param.value_type == "pair" else param.size
        options.update(type=param_type(param), metavar=",".join(["X"] * count))
    return options


def argument_type(name: str, parse):
    """An argparse type from a glshade parser: its GlshadeError becomes argparse's usage
    error (one line, exit 2); ``name`` is what argparse calls the type."""

    def parsed(text: str):
        try:
            return parse(text)
        except GlshadeError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None

    parsed.__name__ = name
    return parsed


def param_type(param: Param):
    """argparse type of a parameter: its text parsed by the declaration (units allowed)."""
    return argument_type(param.path, param.parse)


def quantity_list(path: str):
    """argparse type of a comma-separated list of one parameter's values (units allowed)."""
    return argument_type(
        path,
        lambda text: [
            registry().param(path).parse(part) for part in text.split(",") if part.strip()
        ],
    )


def length_mm(text: str) -> float:
    from glshade.units import parse_quantity

    return parse_quantity(text, "mm", "length")


def _settings_params(method: str | None = None) -> list[tuple[Any, Param]]:
    """``(instrument, parameter)`` of every registered instrument's declared settings
    (only ``method``'s when given), glshade's own first."""
    from glshade.instruments.registry import instruments
    from glshade.params import declared_params

    return [
        (item, declared)
        for name, item in instruments().by_name.items()
        if method is None or name == method
        for declared in declared_params(item.settings_type)
    ]


def settings_dest(declared: Param) -> str:
    """The argparse destination of an instrument setting's flag."""
    return f"measure_{declared.key}"


def add_settings_flags(
    p: argparse.ArgumentParser | argparse._ArgumentGroup,
    method: str | None = None,
    defaults: dict[str, Any] | None = None,
) -> None:
    """The short flags the registered instruments' settings declare (only ``method``'s
    when given); an unset flag takes its declared default, or the command's own
    (``defaults`` by key, said in the help instead)."""
    from dataclasses import replace

    for item, declared in _settings_params(method):
        if declared.flag is None:
            continue
        unit = f" {declared.unit}" if declared.unit else ""
        default = (defaults or {}).get(declared.key, declared.default)
        shown = replace(declared, default=default).default_text()
        p.add_argument(
            declared.flag,
            dest=settings_dest(declared),
            metavar=declared.key.upper() if declared.value_type != "choice" else None,
            choices=declared.choices or None,
            help=f"{declared.doc} ({item.name}; default {shown}{unit})",
        )


def settings_flags_given(args: argparse.Namespace, method: str | None = None) -> list[str]:
    """The instrument settings' flags the command line set (only ``method``'s when given)."""
    return [
        declared.flag
        for _, declared in _settings_params(method)
        if declared.flag is not None and getattr(args, settings_dest(declared), None) is not None
    ]


#: The table of ``--set`` paths that set an instrument's settings, not the scene.
MEASURE_TABLE = "measure."


def scene_settings(args: argparse.Namespace) -> list[str]:
    """The ``--set`` items that set the scene; ``measure.KEY`` items are the measuring
    instrument's (:func:`instrument_settings`), refused in one line by a command that
    measures nothing (it would ignore them)."""
    items = list(args.settings or ())
    scene_items = [item for item in items if not item.strip().startswith(MEASURE_TABLE)]
    measures = any(hasattr(args, settings_dest(p)) for _, p in _settings_params() if p.flag)
    if len(scene_items) < len(items) and not measures:
        typed = next(item for item in items if item.strip().startswith(MEASURE_TABLE))
        raise GlshadeError(
            f"--set {typed.strip()}: an instrument's setting, and glshade {args.command} "
            "measures nothing (measure, optimize and paper take it)"
        )
    return scene_items


def _measure_settings(args: argparse.Namespace) -> list[tuple[str, str, str]]:
    """``(typed, key, value text)`` of every ``--set measure.KEY=VALUE``."""
    found = []
    for item in getattr(args, "settings", None) or ():
        name, sep, text = item.strip().partition("=")
        if name.strip().startswith(MEASURE_TABLE):
            if not sep:
                raise GlshadeError(f"--set {item}: must be NAME=VALUE")
            key = name.strip()[len(MEASURE_TABLE) :].strip().replace("-", "_")
            found.append((f"--set {name.strip()}", key, text))
    return found


def scene_measure_table(args: argparse.Namespace, scene: Scene) -> MeasureTable:
    """The ``[measure]`` table of the command line's scene file (empty without one):
    how the file says its scene is measured, checked."""
    from glshade.instruments.table import MeasureTable, file_measure_table

    if args.scene is None:
        return MeasureTable()
    return file_measure_table(args.scene, scene.active.emitter.measured_by)


def instrument_settings(
    args: argparse.Namespace,
    method: str,
    chosen_by: str = "",
    table: MeasureTable | None = None,
) -> Any:
    """The settings of instrument ``method``: its defaults, the scene file's ``[measure]``
    ``table`` where it is for this instrument (a warning where it names another), then
    the command line's flags and ``--set measure.KEY``; a flag of another instrument, or
    a bad value named by its flag, is one line. ``chosen_by``: how the command line chose
    the instrument (``--method pmd``)."""
    from glshade.instruments.registry import instrument

    chosen = instrument(method)
    if table is not None and table.values and table.method != chosen.name:
        theirs = instrument(table.method or chosen.name).title
        by = chosen_by or f"--method {chosen.name}"
        warn([f"{table.source}: its [measure] is {theirs}'s: {by} measures with its own settings"])
    for item, declared in _settings_params():
        if item is not chosen and declared.flag in settings_flags_given(args, item.name):
            raise GlshadeError(
                f"{declared.flag}: belongs to {item.title} (--method {item.name}), not to "
                f"{chosen_by or f'--method {chosen.name}'}"
            )
    declared_by = {declared.key: declared for _, declared in _settings_params(chosen.name)}
    typed = [
        (declared.flag, declared.key, getattr(args, settings_dest(declared), None))
        for declared in declared_by.values()
        if declared.flag
    ]
    given = table.for_method(chosen.name) if table is not None else {}
    for spelled, key, text in [*typed, *_measure_settings(args)]:
        if text is None:
            continue
        found = declared_by.get(key)
        owner = next((item for item, d in _settings_params() if d.key == key), None)
        if found is None and owner is not None:
            raise GlshadeError(
                f"{spelled}: belongs to {owner.title} (--method {owner.name}), not to "
                f"{chosen_by or f'--method {chosen.name}'}"
            )
        if found is None:
            raise GlshadeError(
                f"{spelled}: not a setting of {chosen.title} (--method {chosen.name}); its "
                f"settings: {', '.join(MEASURE_TABLE + name for name in declared_by)}"
            )
        declared = found
        try:
            given[key] = declared.check(declared.parse(text))
        except (SceneError, QuantityError) as exc:
            allowed = getattr(exc, "allowed", declared.allowed())
            raise GlshadeError(f"{spelled}: must be {allowed}, got {text.strip()}") from None
    try:
        return chosen.settings_type(**given)
    except SceneError as exc:
        raise GlshadeError(str(exc)) from None


def scene_from_args(args: argparse.Namespace) -> Scene:
    """The scene a ``render``/``measure``/``optimize`` call describes: the file (or the
    default scene), resized by ``--size`` (:func:`sized`), then the short flags, then
    ``--set NAME=VALUE`` in order. A bad value is named as the user typed it (``--sigma2``,
    ``--set theta``, or the dotted path of ``--set``), not by the fields it sets, also
    where a check over several values of a table refuses it (``--bit-depth``)."""
    # the file, or the scene every default makes (the paper's flat plate): a surface given
    # by a flag takes its parameters' defaults exactly as a file naming only its kind does
    scene = Scene.load(args.scene) if args.scene is not None else Scene()
    tables: dict[str, dict[str, object]] = {}
    typed: dict[str, str] = {}  # parameter path -> how the user typed it
    for param in registry().params():
        value = getattr(args, flag_dest(param), None) if param.flag is not None else None
        if value is not None:
            tables.setdefault(param.table, {})[param.key] = checked(param, value, param.flag)
            typed[param.path] = param.flag or param.path
    # later settings win; all are applied at once, so values that only make sense together
    # (a kind and its file) can be given together
    read_settings(scene_settings(args), scene, tables, typed)
    scene = sized(scene, args.size, tables, typed)
    with named_as_typed(typed):
        scene = scene.updated(**tables) if tables else scene
    check_station(scene)
    return scene


#: Pixels across of the grid a posed station's screen is looked for on.
STATION_CHECK_GRID = 16


def check_station(scene: Scene) -> None:
    """A station that is not the paper's rig shows its screen to the camera, from the
    front: else one line says which (a rig scene is not checked, so its numbers, an
    unresolved case included, stay what they were)."""
    from glshade.scene.station import is_rig

    if not is_rig(scene):
        from glshade.oracle.station_report import refuse_unseen, trace_grid

        refuse_unseen(scene, trace_grid(scene, STATION_CHECK_GRID))


def sized(
    scene: Scene, size: int | None, tables: dict[str, dict[str, object]], typed: dict[str, str]
) -> Scene:
    """``--size N`` applied to the scene the file (or the defaults) describes, before the
    values typed on the command line (``tables``, typed as ``typed`` says): N pixels
    across with the file's field of view (:meth:`Scene.with_size` rescales the pixel
    pitch), and what the command line then sets is kept as typed, so a typed
    ``camera.pixel_pitch`` or ``camera.height`` wins and the field of view follows. A
    typed ``camera.width`` other than N contradicts ``--size``: one line naming both."""
    if size is None:
        return scene
    width = tables.get("camera", {}).get("width")
    if width is not None and width != size:
        how = typed.get("camera.width", "camera.width")
        how = how if how.startswith("-") else f"--set {how}"
        raise GlshadeError(
            f"--size {size} and {how}={width} conflict: both set camera.width (the image's "
            "pixels across); give one of them"
        )
    with named_as_typed({"camera.width": "--size", "camera.height": "--size"}):
        return scene.with_size(size)


def read_settings(
    items: Sequence[str],
    scene: Scene,
    tables: dict[str, dict[str, object]],
    typed: dict[str, str],
    others: Sequence[str] = (),
) -> None:
    """``--set NAME=VALUE`` items parsed into ``tables`` (table -> key -> value; a later
    item wins), each path's spelling recorded in ``typed`` (``--set theta`` for a short
    name, the path itself for a dotted one) to name a bad value as it was typed."""
    for item in items:
        name, path, value = _parse_setting(item, scene, tables, others)
        table, _, key = path.partition(".")
        tables.setdefault(table, {})[key] = value
        typed[path] = path if name == path else f"--set {name}"


def with_settings(
    scene: Scene,
    items: Sequence[str],
    others: Sequence[str] = (),
    size: int | None = None,
    default_size: int | None = None,
) -> Scene:
    """``scene`` with ``--set NAME=VALUE`` items and ``--size`` applied as ``render``
    applies them (the viewer's scripted ``--set`` uses it; ``others``: its own names,
    offered where a name is unknown). ``default_size``: the size without ``--size``,
    unless ``camera.width`` is typed."""
    tables: dict[str, dict[str, object]] = {}
    typed: dict[str, str] = {}
    read_settings(items, scene, tables, typed, others)
    if size is None and "width" not in tables.get("camera", {}):
        size = default_size
    scene = sized(scene, size, tables, typed)
    with named_as_typed(typed):
        return scene.updated(**tables) if tables else scene


@contextlib.contextmanager
def named_as_typed(typed: dict[str, str]):
    """A SceneError raised inside names the flag the user typed (``--bit-depth
    (sensor.bit_depth)``) where ``typed`` maps the field it names to one."""
    try:
        yield
    except SceneError as exc:
        flag = typed.get(exc.field)
        if flag is None or flag == exc.field:
            raise
        raise SceneError(f"{flag} ({exc.field})", exc.allowed, exc.got) from None


def checked(param: Param, value: object, typed: str | None = None) -> object:
    """``value`` checked against its own declaration first (a selector's names are checked
    when the scene is built), so a bad value is named ``typed`` (a flag) or by its own
    path, never by the fields a shorthand sets (``defect.sigma2`` sets two variances)."""
    if param.value_type == "choice":
        return value
    try:
        param.check(value)
    except SceneError as exc:
        name = exc.field if typed is None else f"{typed} ({exc.field})"
        raise SceneError(name, exc.allowed, exc.got) from None
    return value


def _spelling(name: str) -> str:
    """A short name with ``-``, ``_`` and spaces alike, in lower case."""
    return "_".join(name.strip().lower().replace("-", " ").replace("_", " ").split())


def short_names() -> dict[str, tuple[Param, ...]]:
    """Every short name a parameter declares, and the parameters declaring it: its short
    flag without the dashes (``theta`` for ``--theta``), its viewer control's name
    (``stripe_sigma``), and a choice's key where it has no flag (``outside``). Every
    command's ``--set`` and the viewer's controls take these names."""
    names: dict[str, dict[str, Param]] = {}
    for param in registry().params():
        spellings = []
        if param.flag is not None:
            spellings.append(param.flag.lstrip("-"))
        if param.control is not None:
            spellings.append(param.control.name)
        if param.value_type == "choice" and param.flag is None:
            spellings.append(param.key)
        for spelling in spellings:
            names.setdefault(spelling, {})[param.path] = param
    return {name: tuple(params.values()) for name, params in names.items()}


def setting_param(name: str, others: Sequence[str] = ()) -> Param:
    """The parameter a command line's ``--set NAME=...`` sets: ``NAME`` a dotted path
    (``camera.theta_deg``) or a short name (:func:`short_names`: ``theta``), spelled as
    declared or with ``-``, ``_`` and spaces alike (``f_number``). An unknown name, or one
    that two parameters declare, is one line (a GlshadeError) listing the close matches;
    ``others``: the caller's own names (the viewer's ``view``), offered among them."""
    name = name.strip()
    if "." in name:
        return registry().param(name)  # an unknown table or key: a SceneError naming it
    names = short_names()
    found = names.get(name)
    if found is None:
        wanted = _spelling(name)
        matches = {
            param.path: (spelling, param)
            for spelling, params in names.items()
            if _spelling(spelling) == wanted
            for param in params
        }
        found = tuple(param for _, param in matches.values())
        if len(found) > 1:
            which = " or ".join(f"{spelling!r} ({path})" for path, (spelling, _) in matches.items())
            raise GlshadeError(
                f"--set {name}: ambiguous short name: it may be {which}; type one of those"
            )
    if len(found) == 1:
        return found[0]
    if found:  # two parameters declare this very spelling
        paths = " or ".join(param.path for param in found)
        raise GlshadeError(
            f"--set {name}: ambiguous short name: it may be {paths}; type the dotted path"
        )
    known = sorted({*names, *others})
    close = difflib.get_close_matches(name, known, n=5, cutoff=0.6) or difflib.get_close_matches(
        _spelling(name), [_spelling(n) for n in known], n=5, cutoff=0.6
    )
    hint = f"close matches: {', '.join(close)}" if close else f"short names: {', '.join(known)}"
    raise GlshadeError(
        f"--set {name}: unknown setting; {hint}; or a dotted path such as camera.theta_deg "
        "(docs/scene-format.md)"
    )


def parse_setting(
    item: str, scene: Scene | None = None, pending: dict[str, dict[str, object]] | None = None
) -> tuple[str, object]:
    """``NAME=VALUE`` -> the parameter's path and its value parsed by its declaration
    (:func:`setting_param`: ``NAME`` a dotted path or a short name; a SceneError names an
    unknown path, and the value is checked as typed). A named entry of a table
    parameter, ``surface.parameters.a=0.2``, sets that entry and keeps the table's others
    (those already ``pending``, else those of ``scene``)."""
    _, path, value = _parse_setting(item, scene, pending)
    return path, value


def _parse_setting(
    item: str,
    scene: Scene | None = None,
    pending: dict[str, dict[str, object]] | None = None,
    others: Sequence[str] = (),
) -> tuple[str, str, object]:
    """:func:`parse_setting`, with the name as typed first."""
    name, sep, text = item.partition("=")
    name = name.strip()
    if not sep or not name:
        raise GlshadeError(
            f"--set {item!r}: expected NAME=VALUE, a dotted path or a short name such as "
            "camera.theta_deg=15 or theta=15"
        )
    entry = registry().entry(name)
    if entry is not None:
        return (name, *_table_entry(entry[0], entry[1], text, scene, pending or {}))
    param = setting_param(name, others)
    with named_as_typed({param.path: f"--set {name}"} if name != param.path else {}):
        return name, param.path, checked(param, param.parse(text))


def _table_entry(
    param: Param,
    name: str,
    text: str,
    scene: Scene | None,
    pending: dict[str, dict[str, object]],
) -> tuple[str, object]:
    """``table.key.name=VALUE`` for a parameter holding named numbers (a formula's
    ``parameters``): the whole table with ``name`` set (the number checked as the file's
    would be, in the table's unit if it has one)."""
    given = pending.get(param.table, {}).get(param.key)
    if given is None and scene is not None:
        given = scene.value(param.path)
    current = dict(param.check(given or ()))
    current[name] = param.parse_entry(name, text)
    return param.path, checked(param, tuple(current.items()))


def check_memory(cases, settings, threads: int, pooled: bool) -> None:
    """The memory budget (``GLSHADE_MEMORY_BUDGET_MB``) checked for each geometry of
    ``cases`` (a study's first case of each surface, a sweep's first chunk) before the
    run's directory is touched: a run beyond it is refused with nothing written. The
    engine checks every geometry again before tracing it."""
    from glshade.budget import memory_budget_from_env
    from glshade.measure.engine import check_budget

    check_budget(cases, settings, memory_budget_from_env(), threads=threads, pooled=pooled)


def warn(lines) -> None:
    """Print each warning once, as one line on stderr."""
    for line in dict.fromkeys(lines):
        print(f"glshade: warning: {line}", file=sys.stderr)


def one_line(message: str) -> str:
    """``message`` on one line: line breaks become spaces, and any other control character
    (from a file name or an argument) is shown escaped (``\\r``)."""
    return printable(" ".join(part.strip() for part in message.split("\n") if part.strip()))
