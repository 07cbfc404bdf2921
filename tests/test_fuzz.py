"""A seeded mutation fuzzer over the example scenes and sweep files: every mutant ends in a
result or in one line (exit 2), never a traceback, an internal error (exit 1) or a
half-written output.

The seeds are the scene files of ``examples/`` and a scene that sets every optional table
(lens, distortion, sensor, a microfacet lobe). Each mutant applies one to three mutations:
a value replaced by an extreme number (0, -1, 5e-324, 1e308, 10**30, inf, nan), by a
value of the wrong type, by another registered name, by a quantity's text (random digits,
letters, µ, blanks and units in any case, some of them tens of thousands of characters
long); a key or table removed or invented; the file's bytes truncated, flipped or
repeated. Scene mutants are rendered at 8² (and a share measured at 16²) by the real
command line, in this process; sweep-file mutants are planned (their cases counted, the
first built). The unit parser is also fed such texts directly: a number, or one line.

``python tests/test_fuzz.py --count 3000 --seed 7`` runs a longer campaign and prints a
tally (docs/robustness.md records one).
"""

from __future__ import annotations

import argparse
import io
import random
import shutil
import subprocess
import sys
import tomllib
from collections import Counter
from contextlib import redirect_stderr, redirect_stdout
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import tomli_w

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
SCENE_SEEDS = ("panel.toml", "pmd_station.toml", "saddle.toml")
SWEEP_SEEDS = ("paper_study.toml", "pmd_sweep.toml")
#: A scene that sets every optional table (the fuzzer's fourth seed).
EVERYTHING = {
    "camera": {
        "theta_deg": 30.0,
        "f_number": 8.0,
        "aperture_samples": 4,
        "distortion": [0.01, 0.0, 0.0, 0.0, 0.0],
    },
    "emitter": {"period": 3.0, "phase": 0.5},
    "surface": {"kind": "sphere", "radius": -120.0},
    "defect": {"dmax": -0.004, "sigma_x2": 4.0, "sigma_z2": 2.0, "sigma_xz": 0.5},
    "render": {"reflection": "ggx", "roughness": 0.001, "supersample": 2},
    "sensor": {"full_well_e": 5000.0, "read_noise_e": 3.0, "bit_depth": 10, "seed": 3},
}
EXTREMES: tuple[Any, ...] = (
    0,
    -1,
    -0.0,
    5e-324,
    1e-300,
    1e-9,
    0.5,
    3,
    1e6,
    1e300,
    1e308,
    10**30,
    2**63,
    -(2**63),
    float("inf"),
    float("-inf"),
    float("nan"),
)
WRONG_TYPES: tuple[Any, ...] = (
    "text",
    "",
    "5 um",
    "auto",
    "1e999",
    [1.0, 2.0],
    [],
    [[1.0]],
    {"a": 1.0},
    True,
    "../../etc/passwd",
    "\x1b[31mred",
)


#: What a quantity's text is made of, for :func:`random_quantity`.
QUANTITY_CHARACTERS = "0123456789" * 3 + ".+-eE µμ°²^\t_,xMmNnUuCcDdGgRrAaPp"
QUANTITY_UNITS = ("mm", "um", "µm", "μm", "nm", "cm", "m", "deg", "rad", "mrad", "°", "px")
QUANTITY_UNITS += ("mm2", "um^2", "cm²", "Mm", "MM", "Um", "DEG", "Rad", "mRAD", "M", "furlong")
#: Lengths of the long texts: at the parser's limit, just past it, and far beyond.
QUANTITY_LONG = (64, 65, 1000, 60_000)


def random_quantity(rng: random.Random) -> str:
    """A quantity's text as a careless or hostile user types it: a number with a unit in
    any case, random characters, or a very long run of either."""
    shape = rng.random()
    if shape < 0.4:
        number = rng.choice(("5", "-0.5", ".5", "5.", "1e3", "1e-300", "4e6", "nan", "inf", "1_0"))
        blank = rng.choice(("", " ", "  ", "\t"))
        return f"{number}{blank}{rng.choice(QUANTITY_UNITS)}"
    length = rng.randint(0, 20) if shape < 0.8 else rng.choice(QUANTITY_LONG)
    if rng.random() < 0.5:  # a run of one pattern, then junk: what made a regex backtrack
        run = rng.choice(("1", "12", "1 ", "1.", "e1", "µ"))
        tail = rng.choice(("", " x y", "x", "mm", " Mm"))
        return (run * (length // len(run) + 1))[:length] + tail
    return "".join(rng.choice(QUANTITY_CHARACTERS) for _ in range(length))


def registered_names() -> list[str]:
    from glshade.components.registry import registry

    names = {name for param in registry().params() for name in param.choices}
    for param in registry().params():
        names.update(registry().choices(param) or ())
    return sorted(names)


@dataclass(frozen=True)
class Mutant:
    """A mutated file: its name, its bytes and what was done to it."""

    seed: str
    data: bytes
    done: tuple[str, ...]


def _paths(document: dict, prefix: tuple = ()) -> list[tuple]:
    """Every key path of a TOML document (tables and values)."""
    found = []
    for key, value in document.items():
        found.append((*prefix, key))
        if isinstance(value, dict):
            found += _paths(value, (*prefix, key))
    return found


def _set(document: dict, path: tuple, value: Any) -> None:
    for key in path[:-1]:
        document = document[key]
    document[path[-1]] = value


def _delete(document: dict, path: tuple) -> None:
    for key in path[:-1]:
        document = document[key]
    del document[path[-1]]


#: The structured mutations, each as often as it appears.
OPERATIONS = ("extreme", "extreme", "scale", "scale", "scale", "type", "name", "delete")
OPERATIONS += ("invent", "nest", "quantity")


def mutate_document(document: dict, rng: random.Random, names: list[str]) -> str:
    """One structured mutation of ``document`` in place; returns what it did."""
    paths = _paths(document)
    operation = rng.choice(OPERATIONS)
    if not paths or operation == "invent":
        table = rng.choice([*document, "camera", "lens", "surface", ""])
        key = rng.choice(["zoom", "kind", "file", "theta_deg", "x" * 300, "a.b"])
        target = document.setdefault(table, {}) if isinstance(document.get(table, {}), dict) else {}
        target[key] = rng.choice(EXTREMES + WRONG_TYPES)
        return f"invent {table}.{key}"
    path = rng.choice(paths)
    if operation == "scale":  # a plausible value gone astray: the renderer is reached
        return _scaled(document, path, rng)
    if operation == "extreme":
        _set(document, path, rng.choice(EXTREMES))
    elif operation == "type":
        _set(document, path, rng.choice(WRONG_TYPES))
    elif operation == "name":
        _set(document, path, rng.choice(names))
    elif operation == "quantity":
        _set(document, path, random_quantity(rng))
    elif operation == "delete":
        _delete(document, path)
    else:
        _set(document, path, [[[[rng.choice(EXTREMES)]]]] if rng.random() < 0.5 else {"x": {}})
    return f"{operation} {'.'.join(map(str, path))}"


def _scaled(document: dict, path: tuple, rng: random.Random) -> str:
    """Every number under ``path`` times a random factor (0.01 to 100, either sign)."""
    factor = rng.choice((-1.0, 1.0)) * 10 ** rng.uniform(-2.0, 2.0)

    def scaled(value: Any) -> Any:
        if isinstance(value, bool) or not isinstance(value, (int, float, list, dict)):
            return value
        if isinstance(value, list):
            return [scaled(v) for v in value]
        if isinstance(value, dict):
            return {k: scaled(v) for k, v in value.items()}
        return type(value)(value * factor) if isinstance(value, float) else round(value * factor)

    target = document
    for key in path[:-1]:
        target = target[key]
    target[path[-1]] = scaled(target[path[-1]])
    return f"scale {'.'.join(map(str, path))} by {factor:.3g}"


def mutate_bytes(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    """One byte-level mutation: truncate, flip, insert junk, repeat a line."""
    operation = rng.choice(("truncate", "flip", "insert", "repeat"))
    if not data:
        return b"\xff", "junk"
    at = rng.randrange(len(data))
    if operation == "truncate":
        return data[:at], f"truncate at {at}"
    if operation == "flip":
        return data[:at] + bytes([data[at] ^ (1 << rng.randrange(8))]) + data[at + 1 :], "flip"
    if operation == "insert":
        junk = rng.choice([b"\x00", b"\xff\xfe", b"[[", b"=", b'"', b"\n[camera]\n", b"\\u0000"])
        return data[:at] + junk + data[at:], f"insert {junk!r}"
    lines = data.split(b"\n")
    line = rng.randrange(len(lines))
    return b"\n".join(lines[: line + 1] + lines[line:]), f"repeat line {line}"


def _dumps(document: dict) -> bytes:
    try:
        return tomli_w.dumps(document).encode()
    except (TypeError, ValueError):  # a value TOML cannot hold (a nested empty list)
        return b"# unwritable\n"


def mutants(seeds: dict[str, bytes], count: int, seed: int) -> list[Mutant]:
    """``count`` mutants of ``seeds`` (name -> bytes), reproducibly from ``seed``."""
    rng = random.Random(seed)
    names = registered_names()
    out = []
    for _ in range(count):
        name = rng.choice(sorted(seeds))
        data = seeds[name]
        done = []
        if rng.random() < 0.75:
            document = tomllib.loads(data.decode())
            for _ in range(rng.randint(1, 3)):
                done.append(mutate_document(document, rng, names))
            data = _dumps(document)
        else:
            data, what = mutate_bytes(data, rng)
            done.append(what)
        out.append(Mutant(name, data, tuple(done)))
    return out


def scene_seeds(folder: Path) -> dict[str, bytes]:
    """The scene seeds, copied into ``folder`` with the height map they read."""
    shutil.copy(EXAMPLES / "panel.x3p", folder / "panel.x3p")
    seeds = {name: (EXAMPLES / name).read_bytes() for name in SCENE_SEEDS}
    seeds["everything.toml"] = tomli_w.dumps(EVERYTHING).encode()
    return seeds


@dataclass(frozen=True)
class Outcome:
    """How the command line ended: its code, its stderr lines, whether it wrote."""

    code: int
    lines: tuple[str, ...]
    wrote: bool

    def problem(self) -> str | None:
        """Why this outcome breaks the rule (None: a result, or one line and exit 2)."""
        errors = [line for line in self.lines if not line.startswith("glshade: warning: ")]
        if self.code == 0:
            if errors or not self.wrote:
                return f"exit 0 but {errors or 'nothing written'}"
            return None
        if self.code != 2:
            return f"exit {self.code}: {self.lines}"
        if len(errors) != 1 or not errors[0].startswith("glshade: error: "):
            return f"exit 2 but {errors}"
        if self.wrote:
            return "exit 2 but an output was written"
        return None


def run_scene(folder: Path, mutant: Mutant, index: int, command: str) -> Outcome:
    """The mutant rendered (8²) or measured (16²) by the command line, in this process."""
    from glshade.app.cli import main

    scene = folder / f"m{index}.toml"
    scene.write_bytes(mutant.data)
    output = folder / f"m{index}.png"
    if command == "render":
        argv = ["render", str(scene), "--size", "8", "-o", str(output)]
    else:
        argv = ["measure", str(scene), "--size", "16", "--json"]
    err = io.StringIO()
    with redirect_stderr(err), redirect_stdout(io.StringIO()) as out:
        code = main(argv)
    wrote = output.exists() if command == "render" else bool(out.getvalue().strip())
    output.unlink(missing_ok=True)
    scene.unlink()
    return Outcome(code, tuple(err.getvalue().strip().splitlines()), wrote)


def run_sweep_file(folder: Path, mutant: Mutant, index: int) -> str | None:
    """A sweep-file mutant planned: its cases counted and the first built, or one line."""
    from glshade.errors import GlshadeError
    from glshade.sweep.spec import load_spec

    path = folder / f"s{index}.toml"
    path.write_bytes(mutant.data)
    try:
        spec = load_spec(path, size=8)
        spec.count  # noqa: B018 - counted without building the grid
        next(iter(spec.cases()), None)
    except GlshadeError as exc:
        text = str(exc)
        return None if text.strip() and "\n" not in text else f"not one line: {text!r}"
    except Exception as exc:  # noqa: BLE001 - the fuzzer's whole point
        return f"{type(exc).__name__}: {exc}"
    finally:
        path.unlink()
    return None


def sweep_seeds(folder: Path) -> dict[str, bytes]:
    shutil.copy(EXAMPLES / "pmd_station.toml", folder / "pmd_station.toml")
    return {name: (EXAMPLES / name).read_bytes() for name in SWEEP_SEEDS}


# --------------------------------------------------------------------------- the tests
SCENE_MUTANTS = 240
MEASURED_EVERY = 8  # one mutant in 8 is also measured
SWEEP_MUTANTS = 120


@pytest.fixture
def small_budget(monkeypatch):
    """A work budget that keeps a mutant's render under a second (a mutant asking for
    more rays is refused with one line, which is what the fuzzer checks)."""
    monkeypatch.setenv("GLSHADE_MAX_RAYS", str(1 << 16))


@pytest.mark.slow
def test_scene_mutants_end_in_a_result_or_one_line(tmp_path, small_budget):
    """Every mutant: an image (or a measurement), or one line and exit 2. And the fuzzer
    reaches the renderer: a tenth of the mutants at least are valid scenes, rendered."""
    seeds = scene_seeds(tmp_path)
    failures = []
    codes: Counter = Counter()
    for index, mutant in enumerate(mutants(seeds, SCENE_MUTANTS, seed=20261126)):
        commands = ("render", "measure") if index % MEASURED_EVERY == 0 else ("render",)
        for command in commands:
            outcome = run_scene(tmp_path, mutant, index, command)
            codes[(command, outcome.code)] += 1
            if (problem := outcome.problem()) is not None:
                failures.append(f"{command} {mutant.seed} {mutant.done}: {problem}")
    assert failures == []
    assert codes[("render", 0)] >= SCENE_MUTANTS // 10, codes
    assert codes[("render", 2)] >= SCENE_MUTANTS // 10, codes


def test_sweep_file_mutants_plan_or_say_one_line(tmp_path):
    seeds = sweep_seeds(tmp_path)
    failures = [
        f"{mutant.seed} {mutant.done}: {problem}"
        for index, mutant in enumerate(mutants(seeds, SWEEP_MUTANTS, seed=11))
        if (problem := run_sweep_file(tmp_path, mutant, index)) is not None
    ]
    assert failures == []


UNIT_TEXTS = 3000


def parse_unit_text(text: str, unit: str) -> str | None:
    """``text`` parsed as a quantity in ``unit`` and set as a scene value: a number (a
    Scene), or one glshade error line; anything else is the problem returned."""
    from glshade.errors import GlshadeError
    from glshade.scene import Scene
    from glshade.units import parse_quantity

    key = {"mm": "defect.dmax", "mm²": "defect.sigma2", "deg": "camera.theta_deg"}.get(unit)
    try:
        number = parse_quantity(text, unit, "field")
        if not isinstance(number, float):
            return f"not a float: {number!r}"
        if key is not None:
            Scene().with_value(key, text)
    except GlshadeError as exc:
        line = str(exc)
        return None if line.strip() and "\n" not in line and len(line) < 500 else repr(line)
    except Exception as exc:  # noqa: BLE001 - the fuzzer's whole point
        return f"{type(exc).__name__}: {exc}"
    return None


def unit_failures(count: int, seed: int) -> list[str]:
    """``count`` random quantities (:func:`random_quantity`) in random units, each a
    number or one short line: the ones that are neither."""
    rng = random.Random(seed)
    failures = []
    for _ in range(count):
        text, unit = random_quantity(rng), rng.choice(("mm", "µm", "mm²", "deg", "px", ""))
        if (problem := parse_unit_text(text, unit)) is not None:
            failures.append(f"{text[:40]!r} ({len(text)} characters) in {unit!r}: {problem}")
    return failures


def test_unit_texts_parse_or_say_one_line():
    """Random quantities, some of 60 000 characters: a number or one short line. Run in a
    child process with a generous timeout: a backtracking regex, stuck in C, would hang
    this one (the parser is linear: about 3 s for all; the old regex took minutes for one)."""
    code = (
        f"import sys; sys.path.insert(0, {str(Path(__file__).parent)!r}); import test_fuzz; "
        f"print(*test_fuzz.unit_failures({UNIT_TEXTS}, 20261127), sep='\\n')"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == ""


def campaign(count: int, seed: int) -> int:
    """A longer run: every mutant rendered, one in eight measured; prints the tally."""
    import os
    import tempfile
    import time

    os.environ["GLSHADE_MAX_RAYS"] = str(1 << 16)
    tally: Counter = Counter()
    failures = []
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as name:
        folder = Path(name)
        for index, mutant in enumerate(mutants(scene_seeds(folder), count, seed)):
            commands = ("render", "measure") if index % MEASURED_EVERY == 0 else ("render",)
            for command in commands:
                outcome = run_scene(folder, mutant, index, command)
                tally[(command, outcome.code)] += 1
                if (problem := outcome.problem()) is not None:
                    failures.append(f"{command} {mutant.seed} {mutant.done}: {problem}")
        for index, mutant in enumerate(mutants(sweep_seeds(folder), count // 4, seed)):
            problem = run_sweep_file(folder, mutant, index)
            tally[("sweep file", "ok" if problem is None else "FAIL")] += 1
            if problem is not None:
                failures.append(f"sweep {mutant.seed} {mutant.done}: {problem}")
        for problem in unit_failures(count, seed):
            tally[("unit text", "FAIL")] += 1
            failures.append(f"unit text {problem}")
    print(f"{count} scene mutants, {count // 4} sweep-file mutants, {count} unit texts, "
          f"seed {seed}, "
          f"{time.perf_counter() - start:.0f} s")  # fmt: skip
    for key, value in sorted(tally.items(), key=str):
        print(f"  {key}: {value}")
    for failure in failures:
        print("FAIL", failure)
    return 1 if failures else 0


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=3000)
    parser.add_argument("--seed", type=int, default=7)
    options = parser.parse_args()
    sys.exit(campaign(options.count, options.seed))
