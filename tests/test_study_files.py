"""How a study writes its case files: a geometry's cases together, one flush for the
group; the thumbnails on the disk before the case files that vouch for them; nothing
half-written trusted on resume; cases measured before an interruption kept."""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

import pytest

from glshade.files import atomic_write_bytes, flush_files
from glshade.measure import store as measure_store
from glshade.measure.case_files import Rejected
from glshade.study import run as study_run
from glshade.study import store
from glshade.study.plan import StudyPlan, case_key
from glshade.study.run import run_study

SMALL = dict(thetas=(45.0, 5.0), size=128)


def _fsynced(monkeypatch) -> list[str]:
    """The paths ``os.fsync`` is called on from now (through /proc's view of the fd)."""
    seen: list[str] = []
    real = os.fsync

    def record(fd: int) -> None:
        seen.append(os.readlink(f"/proc/self/fd/{fd}"))
        real(fd)

    monkeypatch.setattr(os, "fsync", record)
    return seen


@pytest.mark.skipif(not os.path.isdir("/proc/self/fd"), reason="needs /proc")
def test_files_written_unflushed_are_flushed_once_as_a_group(tmp_path, monkeypatch):
    fsynced = _fsynced(monkeypatch)
    paths = [tmp_path / f"{name}.json" for name in "abc"]
    for path in paths:
        atomic_write_bytes(path, path.name.encode(), within=tmp_path, flush=False)
    assert fsynced == []  # written and renamed, not flushed
    assert [path.read_bytes() for path in paths] == [b"a.json", b"b.json", b"c.json"]
    flush_files([*paths, tmp_path / "gone.json"])  # a file gone meanwhile is skipped
    assert fsynced == [*map(str, paths), str(tmp_path)]  # each file's data, the folder once
    atomic_write_bytes(tmp_path / "d.json", b"d", within=tmp_path)
    assert len(fsynced) == 5 and ".d.json." in fsynced[-1]  # by default: before its rename
    assert not list(tmp_path.glob("*.tmp"))


def test_thumbnails_reach_the_disk_before_the_case_files_that_mark_them_done(tmp_path, monkeypatch):
    plan = StudyPlan(surfaces=("flat",), **SMALL)
    rows = run_study(plan, tmp_path / "study", progress=False).rows[:3]
    out = tmp_path / "again"
    (out / "cases").mkdir(parents=True)
    flushes: list[tuple[list[str], list[str]]] = []
    real = measure_store.flush_files

    def record(paths, what="output"):
        paths = list(paths)
        flushes.append(([Path(p).name for p in paths], sorted(p.name for p in out.glob("cases/*"))))
        real(paths, what)

    monkeypatch.setattr(measure_store, "flush_files", record)
    thumbnails = [b"png-0", None, b"png-2"]
    store.write_cases(out, list(zip(rows, thumbnails, strict=True)))
    keys = [case_key(*row.case) for row in rows]
    # one flush for the group's thumbnails (their data, then the folder), while none of
    # its case files exists yet; the case files, which vouch for themselves, unflushed
    assert flushes == [([f"{keys[0]}.png", f"{keys[2]}.png"], [f"{keys[0]}.png", f"{keys[2]}.png"])]
    assert store.finished(out, keys) == dict(zip(keys, rows, strict=True))
    assert (out / "cases" / f"{keys[2]}.png").read_bytes() == b"png-2"
    store.write_cases(out, [(rows[1], None)])  # a group without thumbnails: no flush
    assert len(flushes) == 1


def test_a_case_file_cut_short_by_a_crash_is_measured_again(tmp_path):
    plan = StudyPlan(surfaces=("flat",), **SMALL)
    first = run_study(plan, tmp_path, progress=False)
    key = case_key(*first.rows[0].case)
    path = tmp_path / "cases" / f"{key}.json"
    path.write_bytes(path.read_bytes()[:40])  # what an unflushed file may be after a crash
    rejected = Rejected()
    assert key not in store.finished(tmp_path, [key], rejected)
    again = run_study(plan, tmp_path, progress=False, notify=lambda line: None)
    assert (again.computed, again.skipped) == (1, len(plan.cases()) - 1)
    timing = {"trace_s", "shade_s", "contours_s", "continuous_s"}
    assert [{k: v for k, v in r.items() if k not in timing} for r in again.rows] == [
        {k: v for k, v in r.items() if k not in timing} for r in first.rows
    ]


def test_cases_measured_before_an_interruption_are_kept(tmp_path, monkeypatch):
    """An interruption in the middle of a geometry's cases: those measured by then are
    written (not left unwritten until their group completes), and a rerun resumes them."""
    plan = StudyPlan(surfaces=("flat",), **SMALL)
    real = study_run.open_executor

    class Stop(Exception):
        pass

    class Interrupted:
        def __init__(self, executor):
            self.executor = executor

        def measured(self, cases, settings, extra):
            for count, measured in enumerate(self.executor.measured(cases, settings, extra)):
                if count == 3:
                    raise Stop
                yield measured

    @contextlib.contextmanager
    def interrupted(distribution, renderer=None):
        with real(distribution, renderer) as executor:
            yield Interrupted(executor)

    monkeypatch.setattr(study_run, "open_executor", interrupted)
    with pytest.raises(Stop):
        run_study(plan, tmp_path, progress=False)
    assert len(list((tmp_path / "cases").glob("*.json"))) == 3  # 3 of the first 8-case group
    monkeypatch.undo()
    resumed = run_study(plan, tmp_path, progress=False)
    assert (resumed.skipped, resumed.computed) == (3, len(plan.cases()) - 3)
    assert not list(tmp_path.rglob("*.tmp"))
