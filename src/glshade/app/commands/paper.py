"""``glshade paper``: the paper's whole study (Table 1) measured by an instrument with a
study (:mod:`glshade.app.studies`: the stripe metric's, :mod:`.paper_stripes`, by
default; phase measuring's, :mod:`.paper_pmd`), its figures and its report."""

from __future__ import annotations

import argparse
from pathlib import Path

from glshade.app.args import add_run_flags, path_arg, quantity_list, warn
from glshade.app.studies import refuse_other_flags, study_kind, study_kinds
from glshade.errors import GlshadeError

#: ``glshade paper --help``'s description.
_PAPER_DESCRIPTION = (
    "Run Table 1 of the paper (9 theta x 4 sigma2 x 2 dmax on flat, cylinder and sphere) and "
    "write results.csv, image grids, visibility plots, the Fig. 9 contour overlay and "
    "report.md. Rerunning with the same --out resumes: finished cases are skipped. The "
    "directory is locked while a run uses it; one that holds a study with another plan is "
    "refused unless --overwrite. --method pmd measures the same cases with a phase-measuring "
    "station and writes pmd_results.csv, pmd_report.md and pmd_*.png beside the stripe study "
    "(docs/study.md)."
)


def add(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "paper",
        help="run the paper's whole study (the main job)",
        description=_PAPER_DESCRIPTION,
    )
    _add_output_flags(p)
    p.add_argument(
        "--as-sweep",
        type=path_arg,
        metavar="FILE",
        help="write the study's cases as a sweep file (FILE.toml: its grid, size and "
        "[measure] table) instead of running it: glshade sweep measures the same scenes "
        "with the same settings, with any --method",
    )
    _add_plan_flags(p)
    _add_run_flags(p)
    _add_method_flags(p)


def _write_sweep(path: Path, data: dict, plan) -> int:
    """The study's cases written as the sweep file ``path`` (nothing measured)."""
    from glshade.files import atomic_write_bytes, check_output
    from glshade.sweep.spec import sweep_toml

    check_output(path, "--as-sweep", (".toml",))
    atomic_write_bytes(path, sweep_toml(data).encode(), "--as-sweep")
    print(
        f"wrote {path}: the study's {len(plan.cases())} cases as a sweep (glshade sweep "
        f"{path} measures them, in this process or on a Dask cluster)"
    )
    return 0


def _add_method_flags(p: argparse.ArgumentParser) -> None:
    """``--method`` (the instruments with a study) and each study's own flags."""
    from glshade.instruments.registry import instrument

    kinds = study_kinds()
    listed = "; ".join(
        f"{name} ({instrument(name).title}: {k.writes})" for name, k in kinds.items()
    )
    p.add_argument(
        "--method",
        choices=tuple(kinds),
        default=next(iter(kinds)),
        help=f"the instrument that measures the study: {listed}",
    )
    for kind in kinds.values():
        kind.add_flags(p)


def _add_output_flags(p: argparse.ArgumentParser) -> None:
    """``glshade paper``'s output directory: ``--overwrite`` and ``--out``."""
    p.add_argument(
        "--overwrite",
        action="store_true",
        help="replace a study with another plan in --out (its results, figures and report are "
        "removed)",
    )
    p.add_argument(
        "--out",
        type=path_arg,
        default=Path("paper_study"),
        metavar="DIR",
        help="output directory (default %(default)s)",
    )


def _listed(values: tuple[float, ...]) -> str:
    """Table 1's values as a list flag takes them."""
    return ",".join(f"{value:g}" for value in values)


def _add_plan_flags(p: argparse.ArgumentParser) -> None:
    """``glshade paper``'s plan: the surfaces, the axes of Table 1 and the image size."""
    from glshade.study.plan import PAPER_DMAXS, PAPER_SIGMA2S, PAPER_THETAS

    p.add_argument(
        "--surfaces",
        default="flat,cylinder,sphere",
        metavar="LIST",
        help="comma-separated surface kinds, or scene files (.toml) of free-form surfaces",
    )
    p.add_argument(
        "--thetas",
        type=quantity_list("camera.theta_deg"),
        metavar="LIST",
        help="camera elevations, degrees, strictly decreasing (default "
        + _listed(PAPER_THETAS)
        + ")",
    )
    p.add_argument(
        "--sigma2s",
        type=quantity_list("defect.sigma2"),
        metavar="LIST",
        help="defect variances, mm² or with a unit (default " + _listed(PAPER_SIGMA2S) + ")",
    )
    p.add_argument(
        "--dmaxs",
        type=quantity_list("defect.dmax"),
        metavar="LIST",
        help="defect depths, mm or with a unit: 0.003,0.005 or 3um,5um (default "
        + ",".join(f"{dmax * 1e3:g}um" for dmax in PAPER_DMAXS)
        + ")",
    )
    p.add_argument(
        "--size",
        type=int,
        default=1024,
        metavar="N",
        help="pixels across, the paper's field of view (default %(default)s)",
    )


def _add_run_flags(p: argparse.ArgumentParser) -> None:
    """How ``glshade paper`` runs: workers, threads, the size confirmation, the progress
    bar and the EGL device."""
    notes = {
        "workers": "0: in this process; auto: 2 when the study is large enough to repay their "
        "start (64 cases at 512² or the like), else 0. With --method pmd the phase-measuring "
        "cases go to N workers only when N is given (auto: in this process; their memory is "
        "several times the stripe metric's)",
        "device": "only with --workers 0",
    }
    words: dict[str, tuple[str, ...]] = {"workers": ("auto",)}
    add_run_flags(p, ("workers", "threads"), {"workers": "auto"}, notes, words)
    p.add_argument(
        "--yes",
        action="store_true",
        help="run a study of more cases (surfaces x thetas x sigma2s x dmaxs) than the "
        "confirmation limit",
    )
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_run_flags(p, ("device",), notes=notes)


def run(args: argparse.Namespace) -> int:
    from glshade.measure.locks import run_lock
    from glshade.study import plan as study
    from glshade.study.run import check_workers

    check_workers(args.threads)  # before --out is touched
    kind = study_kind(args.method)
    refuse_other_flags(args, kind)
    metric = kind.plan_settings(args)
    surfaces = tuple(part.strip() for part in args.surfaces.split(",") if part.strip())
    plan = study.StudyPlan(
        surfaces=surfaces,
        thetas=tuple(args.thetas) if args.thetas is not None else study.PAPER_THETAS,
        sigma2s=tuple(args.sigma2s) if args.sigma2s is not None else study.PAPER_SIGMA2S,
        dmaxs=tuple(args.dmaxs) if args.dmaxs is not None else study.PAPER_DMAXS,
        size=args.size,
        metric=metric,
    )
    study.check_size(plan, args.yes)  # before --out is touched, in both methods
    warn(_unread_tables(plan))
    typed_workers, args.workers = args.workers, paper_workers(args.workers, plan, args.device)
    prepared = kind.prepared(args, plan, typed_workers)  # bad input refused before --out
    if args.as_sweep is not None:
        return _write_sweep(args.as_sweep, kind.sweep_file(plan, prepared), plan)
    with run_lock(args.out):
        return kind.run(args, plan, prepared)


def _unread_tables(plan) -> list[str]:
    """A warning for each scene file among the surfaces whose ``[measure]`` sets
    something: a study measures every case with its own settings (its flags)."""
    from glshade.instruments.table import file_measure_table
    from glshade.study.plan import case_scene, is_scene_file

    lines = []
    for surface in plan.surfaces:
        if is_scene_file(surface):
            scene = case_scene(surface)
            table = file_measure_table(Path(surface), scene.active.emitter.measured_by)
            if table.named or table.values:
                lines.append(
                    f"{surface}: its [measure] is not read by the study (every case is "
                    "measured with the study's settings: its flags)"
                )
    return lines


#: ``--workers auto`` starts worker processes for a study of at least this many pixels to
#: trace and measure (64 cases at 512²): below it their start-up (about 2 s) is not repaid.
AUTO_WORKERS_PIXELS = 64 * 512 * 512


def paper_workers(given: str | int, plan, device: int | None) -> int:
    """The worker processes of a study: ``--workers`` (an integer >= 0, or ``auto``), at
    most as many as this machine's cores and memory budget hold at the plan's size
    (:mod:`glshade.measure.capacity`; ``auto`` takes at most that many)."""
    from glshade.measure.capacity import check_worker_count, worker_limit

    pixels = plan.size * plan.size
    if given == "auto":
        large = len(plan.cases()) * pixels >= AUTO_WORKERS_PIXELS
        fits = worker_limit(pixels, "paper").allowed
        return min(2, fits) if large and device is None and fits > 1 else 0
    try:
        workers = int(given)
    except ValueError:
        workers = -1
    if not 0 <= workers <= 256:
        raise GlshadeError(f"--workers: must be auto or an integer in [0, 256], got {given}")
    if workers:
        check_worker_count(workers, pixels, "paper", in_process=True)
    if workers and device is not None:
        raise GlshadeError(
            "--device: only with --workers 0 (worker processes take the EGL device of their "
            "CUDA_VISIBLE_DEVICES)"
        )
    return workers
