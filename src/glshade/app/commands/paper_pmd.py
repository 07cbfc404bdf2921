"""``glshade paper --method pmd``: the paper's study measured by a phase-measuring
deflectometry station (docs/study.md, "The study under phase measuring"). Its flags are
added to ``glshade paper``'s parser (:mod:`glshade.app.commands.paper`) here; a flag of
one instrument given to the other is refused in one line (exit 2) before anything is
written."""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from glshade.app.args import (
    add_settings_flags,
    instrument_settings,
    param_type,
    settings_flags_given,
    warn,
)
from glshade.app.studies import StudyKind, measure_table_of
from glshade.components.registry import registry
from glshade.errors import GlshadeError
from glshade.files import read_regular
from glshade.oracle.advice import scene_warnings
from glshade.process import reuse_freed_memory
from glshade.study.pmd_plan import MODULATION_SHARE

if TYPE_CHECKING:
    from glshade.study.plan import StudyPlan

#: The station's chain: flag -> (the scene parameter it sets, the study's default, what
#: it is).
CHAIN_FLAGS = {
    "--supersample": ("render.supersample", 2, "rays per pixel side: the pixel's footprint"),
    "--full-well": ("sensor.full_well_e", 10000.0, "the sensor's full well, electrons"),
    "--read-noise": ("sensor.read_noise_e", 5.0, "the sensor's read noise, electrons rms"),
    "--bit-depth": ("sensor.bit_depth", 12, "the sensor's bits: 8, 10, 12 or 16"),
    "--seed": ("sensor.seed", 0, "the seed of the sensor's noise"),
    "--shifts": ("emitter.shifts", 4, "phase steps per fringe period, at least 3"),
}


#: The chain's fields, by flag.
CHAIN_FIELDS = {
    "--supersample": "supersample",
    "--full-well": "full_well_e",
    "--read-noise": "read_noise_e",
    "--bit-depth": "bit_depth",
    "--seed": "seed",
    "--shifts": "shifts",
}


#: The PMD-only flags that are neither the chain's nor the instrument's settings: flag ->
#: destination.
OTHER_FLAGS = {"--periods": "periods"}


#: The study's own defaults of the instrument's settings (a stricter validity threshold
#: than a single measurement's: the study's report compares cases at their edges).
STUDY_SETTINGS = {"modulation_share": MODULATION_SHARE}


def _dest(flag: str) -> str:
    return "pmd_" + flag.lstrip("-").replace("-", "_")


class PmdStudy(StudyKind):
    """Phase measuring's study: the paper's cases measured by a PMD station, beside the
    stripe study (run first where ``--out`` has no results.csv)."""

    name = "pmd"
    writes = (
        "a phase-measuring station: pmd_results.csv, pmd_report.md and pmd_*.png beside the "
        "stripe study, running that first where --out has no results.csv"
    )

    def add_flags(self, parser: argparse.ArgumentParser) -> None:
        add_pmd_paper_flags(parser)

    def flags_given(self, args: argparse.Namespace) -> list[str]:
        return pmd_flags_given(args)

    def prepared(self, args: argparse.Namespace, plan: StudyPlan, workers: str) -> Any:
        """The PMD plan of the command line; its cases go to worker processes only when
        ``--workers`` is given (their memory is several times the stripe metric's)."""
        args.pmd_workers = args.workers if workers != "auto" else 0
        if args.pmd_workers:
            from glshade.measure.capacity import check_worker_count

            check_worker_count(args.pmd_workers, plan.size * plan.size, "pmd", in_process=True)
        return pmd_plan(args, plan)

    def sweep_file(self, plan: StudyPlan, prepared: Any) -> dict[str, Any]:
        """The stripe study's grid with each surface's fringe periods, the chain as axes
        of one value (its columns in the table) and the station's settings."""
        grid = plan.sweep_grid()
        for entry in grid["surface"]:
            entry["emitter.periods"] = list(prepared.coding(entry["label"]))
        chain = prepared.chain
        grid.update(
            {
                "emitter.shifts": [chain.shifts],
                "sensor.full_well_e": [chain.full_well_e],
                "sensor.read_noise_e": [chain.read_noise_e],
                "sensor.bit_depth": [chain.bit_depth],
                "sensor.seed": [chain.seed],
                "render.supersample": [chain.supersample],
            }
        )
        settings = measure_table_of(self.name, prepared.settings)
        return {"size": plan.size, "grid": grid, "measure": settings}

    def run(self, args: argparse.Namespace, plan: StudyPlan, prepared: Any) -> int:
        from glshade.app.commands.paper_stripes import run_stripes

        return cmd_paper_pmd(args, plan, prepared, run_stripes)


def add_pmd_paper_flags(p: argparse.ArgumentParser) -> None:
    """The station's flags on ``glshade paper``."""
    group = p.add_argument_group("phase measuring (--method pmd only)")
    for flag, (path, default, meaning) in CHAIN_FLAGS.items():
        param = registry().param(path)
        group.add_argument(
            flag,
            dest=_dest(flag),
            type=param_type(param),
            metavar="N" if param.value_type == "integer" else "X",
            help=f"{meaning} ({path}; default {default:g})",
        )
    group.add_argument(
        "--periods",
        dest=_dest("--periods"),
        action="append",
        metavar="[SURFACE=]LIST",
        help="fringe periods in mm, finest first, the coarsest at least the screen's 300 mm: "
        "of every surface (2,16,128,1024), or of one (sphere=10,80,640); repeatable. Default: "
        "the finest is the shortest whole mm, at least 2, that spans 3 pixels at every theta "
        "(at 1024 px: 2 mm, 10 mm on the sphere), each period 8 times the one before",
    )
    add_settings_flags(group, PmdStudy.name, STUDY_SETTINGS)


def pmd_flags_given(args: argparse.Namespace) -> list[str]:
    """The station's flags the command line set (its chain's, ``--periods`` and the
    instrument's settings')."""
    flags = [*CHAIN_FLAGS, *OTHER_FLAGS]
    given = [flag for flag in flags if getattr(args, _dest(flag), None) is not None]
    return given + settings_flags_given(args, PmdStudy.name)


def _parse_periods(given: list[str] | None) -> tuple[tuple, tuple]:
    """``--periods`` values: ``(every surface's, ((surface, periods), ...))``."""
    every: tuple = ()
    named: dict[str, tuple] = {}
    parse = registry().param("emitter.periods").parse
    for text in given or ():
        surface, _, values = text.rpartition("=")
        try:
            periods = tuple(float(p) for p in parse(values))
        except GlshadeError as exc:
            raise GlshadeError(f"--periods {text}: {exc}") from None
        if surface:
            named[surface.strip()] = periods
        else:
            every = periods
    return every, tuple(named.items())


def pmd_plan(args: argparse.Namespace, cases_plan):
    """The :class:`~glshade.study.pmd_plan.PmdStudyPlan` of the command line."""
    from glshade.instruments.table import MeasureTable
    from glshade.study.pmd_plan import PmdChain, PmdStudyPlan

    chain_values = {
        CHAIN_FIELDS[flag]: getattr(args, _dest(flag))
        for flag in CHAIN_FLAGS
        if getattr(args, _dest(flag)) is not None
    }
    every, named = _parse_periods(getattr(args, _dest("--periods")))
    unknown = sorted(set(dict(named)) - {_label(s) for s in cases_plan.surfaces})
    if unknown:
        raise GlshadeError(
            f"--periods {unknown[0]}=...: not a surface of this study (its surfaces: "
            f"{', '.join(_label(s) for s in cases_plan.surfaces)})"
        )
    study = MeasureTable(PmdStudy.name, True, dict(STUDY_SETTINGS))
    settings_obj = instrument_settings(args, PmdStudy.name, "--method pmd", study)
    chain = PmdChain(**chain_values, periods=every, surface_periods=named)
    try:
        return PmdStudyPlan(cases_plan, chain, settings_obj)
    except GlshadeError as exc:
        raise GlshadeError(f"--method pmd: {exc}") from None


def _label(surface: str) -> str:
    from glshade.study.plan import surface_label

    return surface_label(surface)


def cmd_paper_pmd(args: argparse.Namespace, cases_plan, plan, run_stripes) -> int:
    """``glshade paper --method pmd`` with ``--out`` locked: the stripe study of
    ``cases_plan`` first where ``--out`` has no ``results.csv`` (``run_stripes(args,
    cases_plan)``, resumable), then the PMD study ``plan`` (:func:`pmd_plan`), its figures
    and its report."""
    from glshade.study.pmd_findings import write_pmd_report
    from glshade.study.pmd_plots import write_pmd_figures
    from glshade.study.pmd_store import RESULTS_NAME
    from glshade.study.store import read_results_csv

    first = plan.scene(plan.surfaces[0], plan.thetas[0], plan.sigma2s[0], plan.dmaxs[0])
    warn(scene_warnings(first))
    out: Path = args.out
    start = time.perf_counter()
    if not (out / "results.csv").exists():
        print(f"{out / 'results.csv'} is missing: running the stripe study first")
        run_stripes(argparse.Namespace(**{**vars(args), "overwrite": False}), cases_plan)
    paper_rows = read_results_csv(out / "results.csv")
    reuse_freed_memory()
    result = _measured(args, plan, out)
    paper_size = _paper_size(out)
    image = (paper_size, paper_size) if paper_size else None
    figures = write_pmd_figures(result.rows, paper_rows, out, plan, image)
    report = write_pmd_report(
        result.rows, paper_rows, out, plan, figures, paper_size, result.seconds, result.computed
    )
    print(
        f"{result.computed} PMD cases computed, {result.skipped} resumed; wrote "
        f"{out / RESULTS_NAME}, {len(figures)} figures and {report} in "
        f"{time.perf_counter() - start:.1f} s"
    )
    return 0


def _measured(args: argparse.Namespace, plan, out: Path):
    """The PMD study run in this process, or on ``--workers`` Dask worker processes."""
    from glshade.gpu.context import GLContext
    from glshade.gpu.renderer import Renderer
    from glshade.measure.executors import Distribution
    from glshade.study.pmd_run import run_pmd_study

    options = {"progress": not args.no_progress, "overwrite": args.overwrite}
    workers = getattr(args, "pmd_workers", 0)
    if workers:  # checked against this machine before --out was touched
        distribution = Distribution(workers=workers, verbose=args.verbose)
        return run_pmd_study(plan, out, distribution=distribution, **options)
    with GLContext(device_index=args.device) as context, Renderer(context) as renderer:
        return run_pmd_study(plan, out, renderer=renderer, **options)


def _paper_size(out: Path) -> int | None:
    """The stripe study's image size, from its manifest (None where unknown)."""
    try:
        size = json.loads(read_regular(out / "study.json", "--out")).get("size")
    except (GlshadeError, OSError, ValueError, AttributeError, RecursionError):
        return None
    return int(size) if isinstance(size, int) else None
