"""The paper's study (SPEC §7, Table 1) as a resumable sweep.

Every case is measured by the one metric pipeline (:class:`glshade.metrics.visibility.Baseline`):
for every (surface, θ) the defect-free scene is traced once and its analysis is shared by
the 8 (σ², dmax) cases of that geometry, which changes no number (a case is a pure
function of its scene and the metric settings; ``tests/test_study.py`` checks the rows
against :func:`glshade.measure`). The GL work stays on the calling thread; the analysis
runs in ``workers`` threads.

Each finished case is written as ``cases/<key>.json`` (plus a thumbnail of its image at
the best phase for the figure grids) atomically, so an interrupted run loses nothing and
a rerun with the same output directory skips what is done. ``results.csv`` is rebuilt
from the case files; its columns are :data:`COLUMNS` (documented in ``docs/results.md``).
"""

from __future__ import annotations

import csv
import io
import json
import math
import time
from collections import deque
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

import cv2
import numpy as np

from glshade.errors import GlshadeError
from glshade.files import atomic_write_bytes, encode_png
from glshade.gpu.renderer import Renderer
from glshade.metrics import contours, physics
from glshade.metrics import visibility as vis
from glshade.metrics.measurement import emitter_map
from glshade.scene import PAPER_SURFACES, Camera, Scene, paper_scene

PAPER_THETAS = (85.0, 75.0, 65.0, 55.0, 45.0, 35.0, 25.0, 15.0, 5.0)
PAPER_SIGMA2S = (1.0, 4.0, 9.0, 16.0)
PAPER_DMAXS = (0.003, 0.005)
#: θ columns of the paper's image grids (Figs. 10, 11, 14, 15, 18, 19).
GRID_THETAS = (85.0, 45.0, 5.0)
#: Side of the thumbnails kept for the grids, pixels.
THUMBNAIL = 256
#: Cases drawn as the Fig. 9 contour overlay, when they are part of the plan: the paper's
#: default scene, and a steep dent at a grazing view whose stripe map folds.
OVERLAY_CASES = {
    ("flat", 45.0, 4.0, 0.005): "fig09_contour_overlay.png",
    ("flat", 5.0, 1.0, 0.005): "fig09_contour_overlay_fold.png",
}
#: Changes whenever the metric's definition changes: case files of another version are
#: never mixed into a study.
METRIC_VERSION = 2


@dataclass(frozen=True)
class Column:
    """One column of ``results.csv``: its name, unit and meaning (docs/results.md)."""

    name: str
    unit: str
    meaning: str


COLUMNS = (
    Column("surface", "", "base surface: flat, cylinder (R 70 mm, axis in the plane of incidence) or sphere (R 70 mm)"),
    Column("theta_deg", "deg", "camera elevation θ above the surface (90 = straight down)"),
    Column("sigma2_mm2", "mm²", "variance σ² of the Gaussian dent (isotropic)"),
    Column("dmax_mm", "mm", "depth of the dent (0.003 mm = 3 µm)"),
    Column("period_mm", "mm", "stripe period on the emitter (2 mm; 10 mm on the sphere, as in the paper)"),
    Column("visibility_px", "px", "the paper's metric: the largest distance between corresponding stripe contours "
           "over the phase sweep, whole pixels of the image (SPEC §6)"),
    Column("visibility_continuous_px", "px", "the limit of the paper's metric for a vanishing phase step and pixel "
           "size, by the same contour rules (sub-pixel)"),
    Column("deflection_px", "px", "how far the dent moves the emitter map: the largest distance between a row r and "
           "the row r0 where v0(r0) = v1(r), in a kept column; equals the continuous visibility where nothing folds"),
    Column("folded", "", "True where the dent's emitter map runs against the defect-free one along some kept column "
           "(the stripe map folds)"),
    Column("islands", "count", "the most stripe pieces the dent cuts off (touching neither a cut column nor the border; "
           "beyond those the defect-free image has) at any phase; never measured"),
    Column("best_phase_mm", "mm", "stripe phase at which visibility_px was reached"),
    Column("unpaired_contours", "count", "stripes reaching a cut column or the border that found no partner at the best "
           "phase (0 in a healthy comparison)"),
    Column("offset_dx_px", "px", "registration offset applied to the defect image, columns (0 for rendered pairs)"),
    Column("offset_dy_px", "px", "registration offset applied to the defect image, rows (0 for rendered pairs)"),
    Column("unresolved_fraction", "fraction", "share of the kept pixels left out because the defect-free stripes span "
           "fewer than 4 px per period there (aliasing)"),
    Column("fold_ratio", "", "closed form 2 κ Dc De / ((Dc + De) sin θ), κ the largest tangential curvature of base "
           "plus dent; the map folds where it exceeds 1 (docs/physics.md)"),
    Column("deflection_law_px", "px", "closed form of deflection_px (docs/physics.md)"),
    Column("visibility_law_px", "px", "closed form of visibility_continuous_px: the deflection, capped by a fold at "
           "b sqrt(2 ln(F/m)) (docs/physics.md)"),
    Column("trace_s", "s", "time to trace the dent's emitter map (GL)"),
    Column("shade_s", "s", "time to binarise the defect image at every phase"),
    Column("contours_s", "s", "time of the contour analysis over the phase sweep (OpenCV)"),
    Column("continuous_s", "s", "time of the deflection and the continuous limit"),
)
CSV_COLUMNS = [c.name for c in COLUMNS]
_INTEGER_COLUMNS = {"islands", "unpaired_contours", "offset_dx_px", "offset_dy_px"}


def columns_markdown() -> str:
    """The table of ``docs/results.md``."""
    lines = ["| column | unit | meaning |", "|---|---|---|"]
    lines += [f"| `{c.name}` | {c.unit or '—'} | {c.meaning} |" for c in COLUMNS]
    return "\n".join(lines)


def _float_list(name: str, values, lo: float, hi: float, closed_hi: bool = False) -> tuple[float, ...]:
    values = tuple(float(v) for v in values)
    if not values:
        raise GlshadeError(f"{name}: must list at least one value")
    for v in values:
        inside = lo < v <= hi if closed_hi else lo < v < hi
        if not (math.isfinite(v) and inside):
            bracket = "]" if closed_hi else ")"
            raise GlshadeError(f"{name}: every value must be in ({lo:g}, {hi:g}{bracket}, got {v:g}")
    if len(set(values)) != len(values):
        raise GlshadeError(f"{name}: values must not repeat, got {', '.join(f'{v:g}' for v in values)}")
    return values


@dataclass(frozen=True)
class StudyPlan:
    """What to sweep: Table 1 by default, at ``size`` pixels across (paper: 1024)."""

    surfaces: tuple[str, ...] = PAPER_SURFACES
    thetas: tuple[float, ...] = PAPER_THETAS
    sigma2s: tuple[float, ...] = PAPER_SIGMA2S
    dmaxs: tuple[float, ...] = PAPER_DMAXS
    size: int = 1024
    metric: vis.MetricSettings = field(default_factory=vis.MetricSettings)

    def __post_init__(self) -> None:
        if not self.surfaces:
            raise GlshadeError("surfaces: must list at least one of " + ", ".join(PAPER_SURFACES))
        for s in self.surfaces:
            if s not in PAPER_SURFACES:
                raise GlshadeError(f"surfaces: unknown surface {s!r}; allowed: {', '.join(PAPER_SURFACES)}")
        if len(set(self.surfaces)) != len(self.surfaces):
            raise GlshadeError("surfaces: must not repeat")
        thetas = _float_list("thetas", self.thetas, 0.0, 90.0)
        if any(a <= b for a, b in zip(thetas, thetas[1:])):
            raise GlshadeError(
                "thetas: must be strictly decreasing, from high to low viewpoints as in the paper "
                f"(85 … 5), got {', '.join(f'{t:g}' for t in thetas)}"
            )
        object.__setattr__(self, "thetas", thetas)
        object.__setattr__(self, "sigma2s", _float_list("sigma2s", self.sigma2s, 0.0, math.inf))
        object.__setattr__(self, "dmaxs", _float_list("dmaxs", self.dmaxs, 0.0, math.inf))
        Camera().resampled(self.size)  # validates the size
        for surface in self.surfaces:
            self.metric.phases(self.scene(surface, self.thetas[0], self.sigma2s[0], self.dmaxs[0]).emitter.period)

    def scene(self, surface: str, theta: float, sigma2: float, dmax: float) -> Scene:
        return paper_scene(surface, theta, sigma2, dmax).with_size(self.size)

    def cases(self) -> list[tuple[str, float, float, float]]:
        return [(s, t, v, d) for s in self.surfaces for t in self.thetas for v in self.sigma2s for d in self.dmaxs]

    def to_dict(self) -> dict:
        data = asdict(self)
        data["surfaces"] = list(self.surfaces)
        data["metric_version"] = METRIC_VERSION
        return data


def case_key(surface: str, theta: float, sigma2: float, dmax: float) -> str:
    """File stem of a case (dmax in µm, as the file names of the figures)."""
    return f"{surface}_theta{theta:g}_sigma2_{sigma2:g}_dmax{dmax * 1000:g}um"


@dataclass
class Timings:
    """Seconds spent per stage over a run (what ``docs/BENCHMARKS.md`` reports)."""

    trace: float = 0.0
    shade: float = 0.0
    contours: float = 0.0
    continuous: float = 0.0
    io: float = 0.0
    figures: float = 0.0


@dataclass
class StudyResult:
    rows: list[dict]
    timings: Timings
    computed: int
    skipped: int
    out_dir: Path


# --------------------------------------------------------------------------- output dir
def prepare_out_dir(out_dir: Path, plan: StudyPlan) -> None:
    """Create (or reuse) the output directory; a directory that holds a study with other
    settings, or one measured with another version of the metric, is refused rather than
    mixed."""
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise GlshadeError(f"--out {out_dir}: is a file, expected a directory")
    try:
        (out_dir / "cases").mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise GlshadeError(f"--out {out_dir}: cannot create it ({exc.strerror})") from None
    probe = out_dir / ".glshade-write-test"
    try:
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        raise GlshadeError(f"--out {out_dir}: not writable ({exc.strerror})") from None
    manifest = out_dir / "study.json"
    wanted = plan.to_dict()
    if manifest.exists():
        try:
            stored = json.loads(manifest.read_text())
        except (OSError, ValueError):
            stored = None
        if stored is not None and _comparable(stored) != _comparable(wanted):
            raise GlshadeError(
                f"--out {out_dir}: holds a study with other settings or an older metric (see its study.json); "
                "use another directory or remove it"
            )
    atomic_write_bytes(manifest, json.dumps(wanted, indent=2).encode())


def _comparable(plan_dict: dict) -> dict:
    """The settings that change results (the case lists may differ: a rerun may add
    surfaces or angles to the same directory)."""
    return {k: plan_dict.get(k) for k in ("size", "metric", "metric_version")}


def load_case(path: Path) -> dict | None:
    try:
        row = json.loads(path.read_text())
    except (OSError, ValueError):
        return None  # a file from an older, interrupted writer: recompute
    return row if isinstance(row, dict) and set(CSV_COLUMNS) <= set(row) else None


# --------------------------------------------------------------------------- the run
def run_study(
    plan: StudyPlan,
    out_dir: Path,
    *,
    workers: int = 1,
    progress: bool = True,
    renderer: Renderer | None = None,
    on_case_done: Callable[[dict], None] | None = None,
    on_surface_done: Callable[[str, list[dict]], None] | None = None,
) -> StudyResult:
    """Run (or resume) the study into ``out_dir``; returns every case's row.

    ``workers``: threads for the analysis (the GL work stays on this thread).
    ``on_case_done(row)`` is called after each case is safely on disk;
    ``on_surface_done(surface, rows)`` once the last case of a surface computed in this
    run is, with all of that surface's rows (the CLI draws its figures there, on this
    thread, while the workers measure the next surface).
    """
    if workers < 1:
        raise GlshadeError(f"--workers: must be an integer >= 1, got {workers}")
    out_dir = Path(out_dir)
    prepare_out_dir(out_dir, plan)
    timings = Timings()
    cases_dir = out_dir / "cases"
    done: dict[str, dict] = {}
    pending = []
    for case in plan.cases():
        row = load_case(cases_dir / f"{case_key(*case)}.json")
        if row is not None:
            done[case_key(*case)] = row
        else:
            pending.append(case)
    skipped = len(done)

    bar = _progress(len(plan.cases()), skipped, progress)
    owns = renderer is None
    renderer = renderer or Renderer()

    left = {surface: sum(case[0] == surface for case in pending) for surface in plan.surfaces}

    def finished(row: dict) -> None:
        done[case_key(row["surface"], row["theta_deg"], row["sigma2_mm2"], row["dmax_mm"])] = row
        if bar is not None:
            bar.update(1)
        if on_case_done is not None:
            on_case_done(row)
        left[row["surface"]] -= 1
        if left[row["surface"]] == 0 and on_surface_done is not None:
            mine = [done[case_key(*c)] for c in plan.cases() if c[0] == row["surface"] and case_key(*c) in done]
            on_surface_done(row["surface"], mine)

    try:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            _run_cases(plan, pending, renderer, pool, timings, out_dir, finished)
    finally:
        if bar is not None:
            bar.close()
        if owns:
            renderer.release()
    rows = [done[case_key(*case)] for case in plan.cases() if case_key(*case) in done]
    start = time.perf_counter()
    write_results_csv(out_dir / "results.csv", rows)
    timings.io += time.perf_counter() - start
    return StudyResult(rows=rows, timings=timings, computed=len(rows) - skipped, skipped=skipped, out_dir=out_dir)


def _progress(total: int, initial: int, enabled: bool):
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, unit="case", desc="glshade paper", dynamic_ncols=True)


def _groups(cases: list[tuple[str, float, float, float]]):
    """Pending cases grouped by (surface, θ): one defect-free trace per group."""
    groups: dict[tuple[str, float], list] = {}
    for case in cases:
        groups.setdefault(case[:2], []).append(case)
    return list(groups.values())


#: Cases traced ahead of the analysis: the GL thread keeps tracing while the workers
#: measure, and at most this many emitter maps wait in memory (4 MiB each at 1024²).
_AHEAD = 16


def _run_cases(plan: StudyPlan, cases, renderer: Renderer, pool: ThreadPoolExecutor, timings: Timings,
               out_dir: Path, finished: Callable[[dict], None]) -> None:
    """Trace every pending case on this (the GL) thread, measure it in the pool, and
    write each result as soon as it is done, in order. The defect-free trace and analysis
    of a (surface, θ) is made once and shared by its cases (:class:`vis.Baseline` labels
    the normal stripes of a phase the first time a worker needs them)."""
    waiting: deque = deque()

    def drain(keep: int) -> None:
        """Write what is done at the head of the queue; wait while more than ``keep`` wait."""
        while len(waiting) > keep or (waiting and waiting[0].done()):
            row, thumbnail, overlay = waiting.popleft().result()
            _write_case(row, thumbnail, overlay, timings, out_dir)
            finished(row)

    for group in _groups(cases):
        normal_scene = plan.scene(*group[0]).without_defect()
        start = time.perf_counter()
        baseline = vis.Baseline(emitter_map(renderer, normal_scene), normal_scene.emitter, plan.metric)
        timings.trace += time.perf_counter() - start
        for case in group:
            scene = plan.scene(*case)
            start = time.perf_counter()
            v1 = emitter_map(renderer, scene)
            trace_s = time.perf_counter() - start
            timings.trace += trace_s
            waiting.append(pool.submit(_analyse_case, case, scene, baseline, v1, trace_s))
            drain(keep=_AHEAD)
    drain(keep=0)


def _write_case(row: dict, thumbnail: bytes | None, overlay, timings: Timings, out_dir: Path) -> None:
    """A finished case on disk: its thumbnail, its overlay figure, and last its JSON (the
    "done" mark a rerun looks for)."""
    timings.shade += row["shade_s"]
    timings.contours += row["contours_s"]
    timings.continuous += row["continuous_s"]
    start = time.perf_counter()
    key = case_key(row["surface"], row["theta_deg"], row["sigma2_mm2"], row["dmax_mm"])
    if thumbnail is not None:
        atomic_write_bytes(out_dir / "cases" / f"{key}.png", thumbnail)
    if overlay is not None:
        from glshade.study.plots import overlay_figure

        case = (row["surface"], row["theta_deg"], row["sigma2_mm2"], row["dmax_mm"])
        overlay_figure(*overlay, out_dir / OVERLAY_CASES[case])
    atomic_write_bytes(out_dir / "cases" / f"{key}.json", json.dumps(row, indent=1).encode())
    timings.io += time.perf_counter() - start


def case_row(case: tuple[str, float, float, float], scene: Scene, result: vis.Visibility) -> dict:
    """A case's row of ``results.csv`` (without the timing columns)."""
    surface, theta, sigma2, dmax = case
    law = physics.laws(scene)
    summary = result.summary()
    return {
        "surface": surface,
        "theta_deg": theta,
        "sigma2_mm2": sigma2,
        "dmax_mm": dmax,
        "period_mm": scene.emitter.period,
        **{k: summary[k] for k in ("visibility_px", "visibility_continuous_px", "deflection_px", "folded", "islands",
                                   "best_phase_mm", "unpaired_contours", "unresolved_fraction")},
        "offset_dx_px": result.offset_px[0],
        "offset_dy_px": result.offset_px[1],
        "fold_ratio": round(law.fold_ratio, 5),
        "deflection_law_px": round(law.deflection_px, 4),
        "visibility_law_px": round(law.visibility_px, 4),
    }


def _analyse_case(case, scene: Scene, baseline: vis.Baseline, v1: np.ndarray, trace_s: float):
    """Everything after the trace, for one case (runs in a worker thread)."""
    result = baseline.measure(v1)
    row = case_row(case, scene, result)
    row.update(trace_s=round(trace_s, 4), shade_s=round(result.seconds.shade, 4),
               contours_s=round(result.seconds.contours, 4), continuous_s=round(result.seconds.continuous, 4))
    thumbnail = None
    if case[1] in GRID_THETAS:
        image = vis.stripe_radiance(v1, scene.emitter, result.best_phase_mm)
        thumbnail = encode_png(cv2.resize(image, (THUMBNAIL, THUMBNAIL), interpolation=cv2.INTER_AREA), bits=8)
    overlay = None
    if case in OVERLAY_CASES:
        normal, defect = baseline.stripes_at(v1, result.best_phase_mm, result.offset_px)
        overlay = (contours.overlay_rgb(normal, defect), result, baseline.columns.start, scene.title())
    return row, thumbnail, overlay


def write_results_csv(path: Path, rows: list[dict]) -> None:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=CSV_COLUMNS, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: row[k] for k in CSV_COLUMNS})
    atomic_write_bytes(Path(path), buffer.getvalue().encode())


def read_results_csv(path: Path) -> list[dict]:
    """``results.csv`` back as typed rows."""
    rows = []
    with open(path, newline="") as fh:
        for raw in csv.DictReader(fh):
            row: dict = {}
            for key, value in raw.items():
                if key == "surface":
                    row[key] = value
                elif key == "folded":
                    row[key] = value == "True"
                elif key in _INTEGER_COLUMNS:
                    row[key] = int(value)
                else:
                    row[key] = float(value)
            rows.append(row)
    return rows
