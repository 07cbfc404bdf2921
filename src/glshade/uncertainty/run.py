"""Running a budget: the reference and every draw measured by phase measuring on the
measuring engine, in this process or on Dask (the executors of :mod:`glshade.measure`,
as a sweep's cases), each finished draw written at once to its case file, so that an
interrupted budget loses only the draws in flight and a rerun measures only the missing.

How the draws ride on the engine: a draw is a :class:`~glshade.instruments.base.Case`,
the truth with the draw's belief as its calibration, measured by the PMD instrument
through :meth:`executor.measured <glshade.measure.executors.LocalExecutor.measured>`.
The engine's per-case ``extra`` hook, which runs where the case is measured (a Dask
worker), reduces the draw's maps to its numbers against the reference
(:func:`~glshade.uncertainty.draws.draw_numbers`); the reference's maps go to the
workers inside the hook (a few hundred kB at 128², once per task). The reference is
measured the same way first, believing the truth. The case files (scalars only: no map
is stored) sit in the output folder's ``cases/``, tied to the scene, the instrument's
settings and the budget by ``budget.json`` (:mod:`glshade.measure.store`: a folder of
another budget is refused unless ``overwrite``; the folder is locked for the run).
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from glshade.instruments.base import Case
from glshade.instruments.registry import instrument
from glshade.measure import store
from glshade.measure.case_files import Rejected
from glshade.measure.executors import Distribution
from glshade.scene import Scene
from glshade.uncertainty.draws import (
    DRAW_NUMBERS,
    REFERENCE_KEY,
    REFERENCE_NUMBERS,
    Reference,
    draw_cases,
    draw_numbers,
    plan_draws,
    reference_of,
)
from glshade.uncertainty.result import CSV, DRAWS_CSV, FIGURE, MARKDOWN, BudgetRun
from glshade.uncertainty.spec import BudgetSpec

if TYPE_CHECKING:
    from glshade.rendering import Renderer

#: A budget's files in its output folder.
MANIFEST = "budget.json"


def _another_budget(stored: dict, wanted: dict) -> str:
    """What a folder of another budget holds, in a refusal: how the two differ."""
    names = {
        "glshade_version": "another glshade version",
        "scene": "another scene",
        "settings": "other phase-measuring settings",
        "budget": "other inputs, draws or seed",
    }
    differing = store.changed(stored, wanted, names)
    if not differing:
        return "a budget of unknown origin (no readable manifest)"
    return "a budget of " + ", ".join(names[key] for key in differing)


#: A budget's files: its manifest, its case files in ``cases/``, its tables and figure
#: (what ``--overwrite`` removes). A new budget of the same scene and settings reuses the
#: case files of the draws it shares (the same belief: a draw's key hashes it).
BUDGET = store.Layout(
    manifest=MANIFEST,
    held=_another_budget,
    resume="the same glshade budget command",
    files=(CSV, MARKDOWN, FIGURE, DRAWS_CSV),
    comparable=("glshade_version", "scene", "settings"),
    command="glshade budget",
)


def truth_of(scene: Scene) -> Scene:
    """The scene a budget measures: as phase measuring measures it (its fringes shown
    where it had stripes), believing the truth."""
    chosen = instrument("pmd")
    return chosen.prepared(scene).with_calibration([])


def manifest_of(scene: Scene, spec: BudgetSpec, settings: Any) -> dict[str, Any]:
    """What ties an output folder to a budget (JSON-able)."""
    import json

    from glshade import __version__

    identity = instrument("pmd").identity(settings)
    return json.loads(
        json.dumps(
            {
                "glshade_version": __version__,
                "scene": {"size": scene.camera.width, **scene.to_dict()},
                "settings": identity,
                "budget": spec.manifest(),
            },
            default=str,
        )
    )


def run_budget(
    scene: Scene,
    spec: BudgetSpec,
    settings: Any,
    out_dir: Path,
    distribution: Distribution = Distribution(),
    *,
    overwrite: bool = False,
    progress: bool = False,
    renderer: Renderer | None = None,
    notify: Callable[[str], None] | None = None,
    on_draw: Callable[[str], None] | None = None,
) -> BudgetRun:
    """Run (or resume) the budget ``spec`` of ``scene`` (the truth; its own calibration is
    dropped: the reference believes the truth) into ``out_dir``, and write its tables and
    figure there (:mod:`glshade.uncertainty.report`).

    Every draw's belief is checked and the memory budget is held against the first case
    before the folder is touched; ``settings``: phase measuring's. ``on_draw(key)`` is
    called after each draw measured now is on disk; ``notify(line)`` is told of case files
    that fail their check (they are measured again)."""
    from glshade.budget import memory_budget_from_env
    from glshade.measure.engine import check_budget

    truth = truth_of(scene)
    instrument("pmd").check_case(truth, settings)
    draws = plan_draws(spec)
    cases = {str(case.key): case for case in draw_cases(truth, spec, draws)}  # beliefs checked
    reference = Case(REFERENCE_KEY, truth)
    pooled = not distribution.on_dask
    check_budget([reference], settings, memory_budget_from_env(), distribution.threads, pooled)
    out_dir = Path(out_dir)
    keys = [REFERENCE_KEY, *cases]
    manifest = manifest_of(truth, spec, settings)
    with store.opened(out_dir, BUDGET, manifest, overwrite, keys=keys):
        rejected = Rejected()
        done = store.load_cases(out_dir, BUDGET, keys, _read, rejected)
        rejected.say(notify)
        pending = [cases[key] for key in cases if key not in done]
        skipped = len(cases) - len(pending)
        start = time.perf_counter()
        if pending or REFERENCE_KEY not in done:
            _measure(truth, reference, pending, settings, distribution, renderer, out_dir, done,
                     _bar(len(cases), skipped, progress), on_draw)  # fmt: skip
        seconds = time.perf_counter() - start
        run = BudgetRun(
            truth,
            spec,
            done[REFERENCE_KEY],
            draws,
            [done[draw.key] for draw in draws],
            len(pending),
            skipped,
            seconds,
            out_dir,
        )
        from glshade.uncertainty.report import write_outputs

        write_outputs(run)
    return run


def _measure(
    truth: Scene,
    reference: Case,
    pending: list[Case],
    settings: Any,
    distribution: Distribution,
    renderer: Renderer | None,
    out_dir: Path,
    done: dict[str, dict[str, Any]],
    bar: Any,
    on_draw: Callable[[str], None] | None,
) -> None:
    """The reference measured (always, where a draw is pending: its maps are what the
    draws are compared with), then the pending draws; each written as it is done."""
    from glshade.measure.where import open_executor

    try:
        with open_executor(distribution, renderer) as executor:
            (measured,) = list(executor.measured([reference], settings, reference_of))
            found: Reference = measured.extra
            record = found.record()
            store.write_case(out_dir, BUDGET, REFERENCE_KEY, record, None)
            done[REFERENCE_KEY] = record
            hook = functools.partial(draw_numbers, found)
            for measured in executor.measured(pending, settings, hook):
                key = str(measured.case.key)
                store.write_case(out_dir, BUDGET, key, measured.extra, None)
                done[key] = measured.extra
                if bar is not None:
                    bar.update(1)
                if on_draw is not None:
                    on_draw(key)
    finally:
        if bar is not None:
            bar.close()


def _read(data: dict[str, Any], key: str) -> tuple[dict[str, Any] | None, str | None]:
    """A checked case file's record, or why it is not one: the numbers of its kind, each
    a finite number or null, a count of pixels, a status. A draw's file of an older
    glshade, without a number this one takes (the slope rms with the tilt removed), is
    not one: its draw is measured again (the one line of the files rejected says so)."""
    names = REFERENCE_NUMBERS if key == REFERENCE_KEY else DRAW_NUMBERS
    for name in names:
        if name not in data:
            return None, f"lacks the budget's number {name} (written by an older glshade)"
        value = data[name]
        if value is None:
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            return None, f"does not hold the budget's number {name}"
        if not math.isfinite(float(value)):
            return None, f"holds a number {name} that is not finite"
    pixels = data.get("pixels")
    if isinstance(pixels, bool) or not isinstance(pixels, int) or pixels < 0:
        return None, "does not hold the budget's pixel count"
    for name in ("status", "status_reason"):
        if not isinstance(data.get(name), str) or len(data[name]) > 4096:
            return None, f"does not hold the budget's {name}"
    return data, None


def _bar(total: int, initial: int, enabled: bool) -> Any:
    from glshade.progress import progress_bar

    return progress_bar(total, "glshade budget", "draw", initial=initial, enabled=enabled)
