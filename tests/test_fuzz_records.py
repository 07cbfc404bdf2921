"""A seeded mutation fuzzer over stored case files (the approach of ``test_fuzz.py``, whose
scene and sweep-file mutants this complements): every mutant is either read back as a
record whose every value is valid, or refused with the one warning line that says it is
measured again; never an exception.

The seeds are real records, the shipped paper study's rows (``docs/paper_study``: an
``ok`` case, an ``unresolved`` one, a PMD ``edge`` case with a ``grazing`` law and one
without a fitted depth), written by glshade's own writers as a study's, a PMD study's
and a sweep's case files. Each mutant applies one to three mutations to the JSON: a
value replaced by an extreme number (0, -1, 5e-324, 1e308, 10**30, 2**63, inf, nan), by
a value of the wrong type, by a long text, a text with a control character or markup,
an unknown status; a plausible number scaled; a field removed or invented; the whole
nested. Most mutants get their checksum recomputed (a forger's file: the values decide);
the others keep the old one, and a fifth have their bytes truncated, flipped or
repeated instead. An accepted record is written on: the study's table read back, the
sweep's Parquet and CSV tables written (where ``unwrap_failures = 2**63`` once raised).

``python tests/test_fuzz_records.py --count 20000 --seed 7`` runs a longer campaign and
prints a tally.
"""

from __future__ import annotations

import argparse
import json
import math
import random
import sys
from collections import Counter
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from glshade.instruments.record import Measurement, PmdMeasurement
from glshade.measure.case_files import CHECKSUM_KEY, ID_KEY, Rejected, case_file_bytes
from glshade.metrics.status import STATUSES
from glshade.study import pmd_store, store
from glshade.study.escape import markdown_text
from glshade.sweep import store as sweep_store
from glshade.sweep.table import TableWriter

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "docs" / "paper_study"
#: The seeds: (store, instrument, the shipped row's case key).
SEEDS = (
    ("study", "paper", "flat_theta45_sigma2_4_dmax5um"),
    ("study", "paper", "sphere_theta5_sigma2_1_dmax3um"),
    ("study", "pmd", "sphere_theta5_sigma2_16_dmax5um"),
    ("sweep", "paper", "cylinder_theta85_sigma2_9_dmax3um"),
    ("sweep", "pmd", "flat_theta45_sigma2_4_dmax5um"),
    ("sweep", "pmd", "sphere_theta5_sigma2_16_dmax5um"),
)
SWEEP_ID = "00c0ffee00c0ffee"
#: A NumPy or pyarrow warning on an accepted record is a defect too.
pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")
EXTREMES: tuple[Any, ...] = (
    0, -1, -0.0, 5e-324, 1e-300, 0.5, 3, 1e6, 1e300, 1e308, 10**30, 2**31, 2**63,
    -(2**63), 10**400, float("inf"), float("-inf"), float("nan"),
)  # fmt: skip
WRONG_TYPES: tuple[Any, ...] = ("text", "", "1e999", "NaN", [1.0], [], {"a": 1.0}, True, None)
TEXTS: tuple[str, ...] = (
    "bogus", "OK", "ok ", "edge\n", "grazing", "x" * 5000, "x" * 4096, "line\nbreak",
    "carriage\rreturn", "\x1b[31mred", "nul\x00", "a\u2028b", "right\u202eleft", "lone \ud800",
    "<script>alert(1)</script>", "| a | b |", "[link](http://evil)", "`code`", "&amp;",
    "../../etc/passwd", "µ σ² θ ° ±",
)  # fmt: skip
OPERATIONS = ("extreme", "extreme", "type", "text", "text", "scale", "scale", "delete", "invent")
OPERATIONS += ("nest", "swap")


@dataclass(frozen=True)
class Seed:
    """A valid case file: its store, instrument, file name (without ``.json``) and JSON."""

    store: str
    instrument: str
    name: str
    content: dict


@dataclass(frozen=True)
class Mutant:
    seed: Seed
    data: bytes
    done: tuple[str, ...]


def shipped_rows() -> dict[tuple[str, str], Any]:
    """The shipped study's rows by (instrument, case key)."""
    rows = {
        ("paper", store.case_key(*r.case)): r for r in store.read_results_csv(STUDY / "results.csv")
    }
    pmd = pmd_store.read_results_csv(STUDY / "pmd_results.csv")
    rows.update({("pmd", store.case_key(*r.case)): r for r in pmd})
    return rows


def make_seeds(folder: Path) -> list[Seed]:
    """The seeds' case files, written by glshade's writers into ``folder``, read back."""
    rows = shipped_rows()
    seeds = []
    for index, (where, instrument, key) in enumerate(SEEDS):
        row = rows[(instrument, key)]
        out = folder / f"seed{index}"
        if where == "study":
            layout = pmd_store.PMD_LAYOUT if instrument == "pmd" else store.STRIPES
            (out / layout.cases).mkdir(parents=True)
            store.write_case(out, row, None, layout)
            path, name = out / layout.cases / f"{key}.json", key
        else:
            record = (PmdMeasurement if instrument == "pmd" else Measurement).from_row(dict(row))
            (out / "cases").mkdir(parents=True)
            sweep_store.write_case(out, SWEEP_ID, record)
            path, name = out / "cases" / f"{SWEEP_ID}.json", SWEEP_ID
        seeds.append(Seed(where, instrument, name, json.loads(path.read_text())))
    return seeds


# --------------------------------------------------------------------------- mutations
def _paths(document: dict, prefix: tuple = ()) -> list[tuple]:
    """Every key path of the record's fields (a sweep's ``outputs`` and ``seconds`` too);
    the case id and checksum are left to the byte mutations."""
    found = []
    for key, value in document.items():
        if key in (ID_KEY, CHECKSUM_KEY):
            continue
        found.append((*prefix, key))
        if isinstance(value, dict):
            found += _paths(value, (*prefix, key))
    return found


def _parent(document: dict, path: tuple) -> dict:
    for key in path[:-1]:
        document = document[key]
    return document


def _scaled(value: Any, rng: random.Random) -> Any:
    """A plausible number gone astray: times 0.01 to 100, either sign (ints stay ints)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return value
    factor = rng.choice((-1.0, 1.0)) * 10 ** rng.uniform(-2.0, 2.0)
    return round(value * factor) if isinstance(value, int) else value * factor


def mutate_document(document: dict, rng: random.Random) -> str:
    """One mutation of a case file's JSON in place; returns what it did."""
    paths = _paths(document)
    operation = rng.choice(OPERATIONS)
    if operation == "invent" or not paths:
        key = rng.choice(["extra", "x" * 300, "status_text", "visibility"])
        document[key] = rng.choice(EXTREMES + WRONG_TYPES + TEXTS)
        return f"invent {key}"
    path = rng.choice(paths)
    parent, key = _parent(document, path), path[-1]
    if operation == "extreme":
        parent[key] = rng.choice(EXTREMES)
    elif operation == "type":
        parent[key] = rng.choice(WRONG_TYPES)
    elif operation == "text":
        parent[key] = rng.choice(TEXTS + STATUSES)
    elif operation == "scale":
        parent[key] = _scaled(parent[key], rng)
    elif operation == "delete":
        del parent[key]
    elif operation == "swap":
        other = rng.choice(paths)
        if other[:-1] == path[:-1]:
            parent[key], parent[other[-1]] = parent[other[-1]], parent[key]
    else:
        parent[key] = [[[[rng.choice(EXTREMES)]]]] if rng.random() < 0.5 else {"x": {}}
    return f"{operation} {'.'.join(path)}"


def mutate_bytes(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    operation = rng.choice(("truncate", "flip", "insert", "repeat"))
    at = rng.randrange(len(data))
    if operation == "truncate":
        return data[:at], f"truncate at {at}"
    if operation == "flip":
        return data[:at] + bytes([data[at] ^ (1 << rng.randrange(8))]) + data[at + 1 :], "flip"
    if operation == "insert":
        junk = rng.choice([b"\x00", b"\xff\xfe", b"[[", b'"', b"\\u0000", b"NaN", b"1e999"])
        return data[:at] + junk + data[at:], f"insert {junk!r}"
    lines = data.split(b"\n")
    line = rng.randrange(len(lines))
    return b"\n".join(lines[: line + 1] + lines[line:]), f"repeat line {line}"


def mutants(seeds: list[Seed], count: int, seed: int) -> list[Mutant]:
    """``count`` mutants of ``seeds``, reproducibly from ``seed``."""
    rng = random.Random(seed)
    out = []
    for _ in range(count):
        source = rng.choice(seeds)
        content = json.loads(json.dumps(source.content))
        if rng.random() < 0.2:
            data, what = mutate_bytes(case_file_bytes(source.name, _record(content)), rng)
            out.append(Mutant(source, data, (what,)))
            continue
        done = [mutate_document(content, rng) for _ in range(rng.randint(1, 3))]
        if rng.random() < 0.8:  # a forger recomputes the checksum
            data = case_file_bytes(source.name, _record(content))
            done.append("checksum recomputed")
        else:
            data = json.dumps(content, indent=1).encode()
        out.append(Mutant(source, data, tuple(done)))
    return out


def _record(content: dict) -> dict:
    return {k: v for k, v in content.items() if k not in (ID_KEY, CHECKSUM_KEY)}


# --------------------------------------------------------------------------- the oracle
LAW_WORDS = ("ok", "grazing")
COUNTS = ("islands", "unpaired_contours", "unwrap_failures")
FRACTIONS = ("unresolved_fraction", "valid_fraction")


def invalid_value(name: str, value: Any) -> str | None:
    """Why an accepted record's field is not valid, by rules written apart from the
    checker's: finite numbers within 1e12, counts non-negative below 2**31, fractions in
    [0, 1], the statuses' words, one-line text of at most 4096 characters."""
    if isinstance(value, str):
        if name == "status" and value not in STATUSES:
            return "an unknown status"
        if name == "pmd_shift_law_status" and value not in LAW_WORDS:
            return "an unknown law status"
        odd = [
            c for c in value if ord(c) < 32 or 0x7F <= ord(c) < 0xA0 or 0xD800 <= ord(c) < 0xE000
        ]
        odd += [c for c in value if c in "\u2028\u2029\u202e"]
        return "a control character" if odd or len(value) > 4096 else None
    if value is None or isinstance(value, bool):
        return None
    if isinstance(value, float) and not math.isfinite(value):
        return "not finite"
    if abs(value) > 1e12:
        return "beyond 1e12"
    if name in COUNTS and not (isinstance(value, int) and 0 <= value < 2**31):
        return "not a count"
    if name in FRACTIONS and not 0 <= value <= 1:
        return "not a fraction"
    return None


def read_mutant(folder: Path, mutant: Mutant, index: int) -> tuple[Any, Rejected]:
    """The mutant read back by its store, as a rerun reads it."""
    seed, rejected = mutant.seed, Rejected()
    out = folder / f"m{index}"
    if seed.store == "study":
        finished = pmd_store.finished if seed.instrument == "pmd" else store.finished
        layout = pmd_store.PMD_LAYOUT if seed.instrument == "pmd" else store.STRIPES
        path = out / layout.cases / f"{seed.name}.json"
        path.parent.mkdir(parents=True)
        path.write_bytes(mutant.data)
        return finished(out, [seed.name], rejected).get(seed.name), rejected
    path = out / "cases" / f"{seed.name}.json"
    path.parent.mkdir(parents=True)
    path.write_bytes(mutant.data)
    found = sweep_store.finished(out, [seed.name], seed.instrument, rejected)
    return found.get(seed.name), rejected


def written_on(folder: Path, mutant: Mutant, record: Any, spec: Any) -> None:
    """An accepted record goes where a run puts it: the study's table (read back), the
    sweep's Parquet and CSV tables; the report's text of its reason."""
    if mutant.seed.store == "study":
        row_class = type(record)
        store.write_results_csv(folder / "table.csv", [record], row_class)
        assert store.read_results_csv(folder / "table.csv", row_class)[0].case == record.case
    else:
        rows = [{"case_id": mutant.seed.name, **record.outputs()}]
        with TableWriter(folder, spec[mutant.seed.instrument]) as table:
            table.add(rows)
            table.finish()
    assert "\n" not in markdown_text(record.status_reason)


def judge(folder: Path, mutant: Mutant, index: int, spec: Any) -> tuple[str, str | None]:
    """``(outcome, problem)``: ``accepted`` or ``rejected``, and why the rule broke (None)."""
    try:
        record, rejected = read_mutant(folder, mutant, index)
        if record is None:
            line = rejected.line() or ""
            head = (
                f"1 case file could not be trusted and is measured again: {mutant.seed.name}.json "
            )
            ok = line.startswith(head) and len(line) > len(head) and "\n" not in line
            return "rejected", None if ok else f"not the one warning line: {line!r}"
        if rejected.line() is not None:
            return "accepted", f"accepted but warned: {rejected.line()!r}"
        bad = [
            (c.name, why)
            for c in record.columns()
            if (why := invalid_value(c.name, getattr(record, c.name)))
        ]
        if bad:
            return "accepted", f"accepted with invalid values {bad}"
        written_on(folder, mutant, record, spec)
        return "accepted", None
    except Exception as exc:  # noqa: BLE001 - the fuzzer's whole point
        return "raised", f"{type(exc).__name__}: {str(exc)[:200]}"


def sweep_specs(folder: Path) -> dict[str, Any]:
    """A tiny sweep of each instrument, planned only (no GL): the tables' columns."""
    import shutil

    from glshade.sweep.spec import load_spec

    shutil.copy(ROOT / "examples" / "pmd_station.toml", folder)
    specs = {}
    for instrument in ("paper", "pmd"):
        path = folder / f"{instrument}.toml"
        path.write_text(
            f'base = "pmd_station.toml"\nsize = 16\n[metric]\nmethod = "{instrument}"\n'
            '[grid]\n"camera.theta_deg" = [45]\n'
        )
        specs[instrument] = load_spec(path)
    return specs


def run(folder: Path, count: int, seed: int) -> tuple[Counter, list[str], Counter]:
    """Every mutant judged: the tally of outcomes, the failures, the accepted changes."""
    seeds = make_seeds(folder)
    specs = sweep_specs(folder)
    tally: Counter = Counter()
    changed: Counter = Counter()
    failures = []
    for index, mutant in enumerate(mutants(seeds, count, seed)):
        outcome, problem = judge(folder, mutant, index, specs)
        tally[(mutant.seed.store, mutant.seed.instrument, outcome)] += 1
        if problem is not None:
            failures.append(
                f"{mutant.seed.store} {mutant.seed.instrument} {mutant.done}: {problem}"
            )
        elif outcome == "accepted" and "checksum recomputed" in mutant.done:
            changed[mutant.done[0].split()[0]] += 1
    return tally, failures, changed


# --------------------------------------------------------------------------- the tests
MUTANTS = 600


def test_seeds_are_accepted_as_written(tmp_path):
    seeds = make_seeds(tmp_path)
    specs = sweep_specs(tmp_path)
    for index, seed in enumerate(seeds):
        data = json.dumps(seed.content).encode()
        assert judge(tmp_path, Mutant(seed, data, ()), index, specs) == ("accepted", None)


def test_case_file_mutants_are_valid_records_or_one_warning(tmp_path):
    """Every mutant: a record with every value valid (and written on), or refused with
    the one warning line; never an exception. The fuzzer reaches both: forged files with
    plausible values are accepted, and every store refuses some."""
    tally, failures, changed = run(tmp_path, MUTANTS, seed=20261127)
    assert failures == []
    for where, instrument, _ in SEEDS:
        assert tally[(where, instrument, "rejected")] >= 10, tally
        assert tally[(where, instrument, "accepted")] >= 3, tally
    assert sum(changed.values()) >= 40 and changed["scale"] >= 10, changed  # forged, yet valid


def campaign(count: int, seed: int) -> int:
    import tempfile
    import time

    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as name:
        tally, failures, changed = run(Path(name), count, seed)
    print(f"{count} case-file mutants, seed {seed}, {time.perf_counter() - start:.0f} s")
    for key, value in sorted(tally.items()):
        print(f"  {' '.join(key)}: {value}")
    print(f"  forged and accepted, by first mutation: {dict(sorted(changed.items()))}")
    for failure in failures:
        print("FAIL", failure)
    return 1 if failures else 0


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=20000)
    parser.add_argument("--seed", type=int, default=7)
    options = parser.parse_args()
    sys.exit(campaign(options.count, options.seed))
