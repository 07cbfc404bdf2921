"""The paper's study (SPEC §7, Table 1) as a resumable sweep.

For every (surface, θ) the defect-free scene is traced once; for every (σ², dmax) the
defect scene is traced once. Each trace yields the emitter map ``v`` (the uv map's
second channel), and every phase of the paper's sweep is shaded from it: for the mirror
model the binarised image at phase ``φ`` is exactly ``|wrap(v - φ)| < w*``
(:func:`glshade.visibility.stripe_half_width`), so no phase is ever re-rendered. The
defect-free image's contour analysis is shared by all defects of its (surface, θ); the
GL context and the program stay alive for the whole sweep.

Each finished case is written as ``cases/<key>.json`` (plus a thumbnail of its image at
the best phase for the figure grids) atomically, so an interrupted run loses nothing and
a rerun with the same output directory skips what is done. ``results.csv`` is rebuilt
from the case files.
"""

from __future__ import annotations

import csv
import io
import json
import math
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

import cv2
import numpy as np

from . import visibility as vis
from .errors import GlshadeError
from .files import atomic_write_bytes, encode_png
from .renderer import Renderer
from .scene import SURFACE_KINDS, Camera, Scene, paper_scene

PAPER_THETAS = (85.0, 75.0, 65.0, 55.0, 45.0, 35.0, 25.0, 15.0, 5.0)
PAPER_SIGMA2S = (1.0, 4.0, 9.0, 16.0)
PAPER_DMAXS = (0.003, 0.005)
#: θ columns of the paper's image grids (Figs. 10, 11, 14, 15, 18, 19).
GRID_THETAS = (85.0, 45.0, 5.0)
#: Side of the thumbnails kept for the grids, pixels.
THUMBNAIL = 256
#: The case shown as the Fig. 9 contour overlay (used when it is part of the plan).
OVERLAY_CASE = ("flat", 45.0, 4.0, 0.005)

CSV_COLUMNS = [
    "surface", "theta_deg", "sigma2_mm2", "dmax_mm", "period_mm",
    "visibility_px", "best_phase_mm", "visibility_continuous_px",
    "unpaired_contours", "folded", "offset_dx_px", "offset_dy_px", "unresolved_fraction",
    "trace_s", "shade_s", "opencv_s", "continuous_s",
]


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

    surfaces: tuple[str, ...] = SURFACE_KINDS
    thetas: tuple[float, ...] = PAPER_THETAS
    sigma2s: tuple[float, ...] = PAPER_SIGMA2S
    dmaxs: tuple[float, ...] = PAPER_DMAXS
    size: int = 1024
    metric: vis.MetricSettings = field(default_factory=vis.MetricSettings)

    def __post_init__(self) -> None:
        if not self.surfaces:
            raise GlshadeError("surfaces: must list at least one of " + ", ".join(SURFACE_KINDS))
        for s in self.surfaces:
            if s not in SURFACE_KINDS:
                raise GlshadeError(f"surfaces: unknown surface {s!r}; allowed: {', '.join(SURFACE_KINDS)}")
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
        return data


def case_key(surface: str, theta: float, sigma2: float, dmax: float) -> str:
    return f"{surface}_theta{theta:g}_sigma2_{sigma2:g}_dmax{dmax:g}"


@dataclass
class Timings:
    """Seconds spent per stage over a run (what ``docs/BENCHMARKS.md`` reports)."""

    trace: float = 0.0
    shade: float = 0.0
    opencv: float = 0.0
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
    settings is refused rather than mixed."""
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
                f"--out {out_dir}: holds a study with other settings (see its study.json); "
                "use another directory or remove it"
            )
    atomic_write_bytes(manifest, json.dumps(wanted, indent=2).encode())


def _comparable(plan_dict: dict) -> dict:
    """The settings that change results (the case lists may differ: a rerun may add
    surfaces or angles to the same directory)."""
    return {"size": plan_dict.get("size"), "metric": plan_dict.get("metric")}


def load_case(path: Path) -> dict | None:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None  # a file from an older, interrupted writer: recompute


# --------------------------------------------------------------------------- the run
def run_study(
    plan: StudyPlan,
    out_dir: Path,
    *,
    workers: int = 1,
    progress: bool = True,
    renderer: Renderer | None = None,
    on_case_done: Callable[[dict], None] | None = None,
) -> StudyResult:
    """Run (or resume) the study into ``out_dir``; returns every case's row.

    ``workers``: threads for the OpenCV analysis (the GL work stays on this thread).
    ``on_case_done(row)`` is called after each case is safely on disk.
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
    try:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            for group in _groups(pending):
                for row in _run_group(plan, group, renderer, pool, timings, cases_dir):
                    done[case_key(row["surface"], row["theta_deg"], row["sigma2_mm2"], row["dmax_mm"])] = row
                    if bar is not None:
                        bar.update(1)
                    if on_case_done is not None:
                        on_case_done(row)
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


def _run_group(plan, group, renderer, pool, timings, cases_dir):
    surface, theta = group[0][:2]
    settings = plan.metric
    normal_scene = plan.scene(surface, theta, group[0][2], group[0][3]).without_defect()
    emitter = normal_scene.emitter
    start = time.perf_counter()
    v0 = renderer.render(normal_scene, ("uv",)).uv[..., 1].copy()
    timings.trace += time.perf_counter() - start

    half_width = vis.stripe_half_width(emitter, settings.threshold)
    if half_width is None or settings.otsu:
        raise GlshadeError(
            "the study shades every phase from the traced emitter map, which needs a fixed threshold "
            "and stripes narrower than a third of the period"
        )
    phases = settings.phases(emitter.period)
    columns = vis.kept_columns(v0.shape[1], settings.keep_fraction)
    resolved = vis.resolved_mask(v0, emitter.period, settings.min_period_px) if settings.min_period_px > 0 else None
    kept_mask = np.isfinite(v0[:, columns])
    unresolved = 0.0
    if resolved is not None and kept_mask.any():
        unresolved = float((kept_mask & ~resolved[:, columns]).sum() / kept_mask.sum())

    def normal_binary(phase: float) -> np.ndarray:
        binary = vis.binarize_v(v0, emitter, phase, half_width)
        return binary & resolved if resolved is not None else binary

    def normal_analysis(phase: float):
        return (float(phase), columns.start, columns.stop), vis.find_stripes(normal_binary(phase)[:, columns])

    start = time.perf_counter()
    normal_cache = dict(pool.map(normal_analysis, phases))
    timings.opencv += time.perf_counter() - start

    traced = []
    for case in group:
        scene = plan.scene(*case)
        start = time.perf_counter()
        v1 = renderer.render(scene, ("uv",)).uv[..., 1].copy()
        trace_s = time.perf_counter() - start
        timings.trace += trace_s
        traced.append(pool.submit(_analyse_case, plan, case, scene, v0, v1, half_width, resolved, normal_cache, trace_s, unresolved))
    for future in traced:
        row, thumbnail, overlay_png, stage = future.result()
        timings.shade += stage["shade"]
        timings.opencv += stage["opencv"]
        timings.continuous += stage["continuous"]
        start = time.perf_counter()
        key = case_key(row["surface"], row["theta_deg"], row["sigma2_mm2"], row["dmax_mm"])
        if thumbnail is not None:
            atomic_write_bytes(cases_dir / f"{key}.png", thumbnail)
        if overlay_png is not None:
            atomic_write_bytes(cases_dir.parent / "fig09_contour_overlay.png", overlay_png)
        atomic_write_bytes(cases_dir / f"{key}.json", json.dumps(row, indent=1).encode())  # the "done" mark
        timings.io += time.perf_counter() - start
        yield row


def _analyse_case(plan, case, scene, v0, v1, half_width, resolved, normal_cache, trace_s, unresolved):
    """Everything after the traces, for one case (runs in a worker thread)."""
    surface, theta, sigma2, dmax = case
    settings = plan.metric
    emitter = scene.emitter
    shade_s = 0.0

    def binaries(phase: float):
        nonlocal shade_s
        start = time.perf_counter()
        pair = vis.binarize_v(v0, emitter, phase, half_width), vis.binarize_v(v1, emitter, phase, half_width)
        shade_s += time.perf_counter() - start
        return pair

    start = time.perf_counter()
    result = vis.paper_visibility(binaries, emitter.period, settings, normal_cache=normal_cache, resolved=resolved)
    opencv_s = time.perf_counter() - start - shade_s
    start = time.perf_counter()
    continuous = vis.continuous_visibility(v0, v1, settings.keep_fraction)
    continuous_s = time.perf_counter() - start

    thumbnail = None
    if theta in GRID_THETAS:
        start = time.perf_counter()
        image = vis.stripe_radiance(v1, emitter, result.best_phase_mm)
        small = cv2.resize(image, (THUMBNAIL, THUMBNAIL), interpolation=cv2.INTER_AREA)
        thumbnail = encode_png(small, bits=8)
        shade_s += time.perf_counter() - start
    overlay_png = None
    if (surface, theta, sigma2, dmax) == OVERLAY_CASE:
        normal, defect = binaries(result.best_phase_mm)
        if resolved is not None:
            normal, defect = normal & resolved, defect & resolved
        overlay_png = encode_png(vis.overlay(normal, defect, settings.keep_fraction))

    row = {
        "surface": surface,
        "theta_deg": theta,
        "sigma2_mm2": sigma2,
        "dmax_mm": dmax,
        "period_mm": emitter.period,
        "visibility_px": result.visibility_px,
        "best_phase_mm": result.best_phase_mm,
        "visibility_continuous_px": round(continuous.visibility_px, 4),
        "unpaired_contours": result.unpaired_contours,
        "folded": continuous.folded or result.unpaired_contours > 0,
        "offset_dx_px": result.offset_px[0],
        "offset_dy_px": result.offset_px[1],
        "unresolved_fraction": round(unresolved, 5),
        "trace_s": round(trace_s, 4),
        "shade_s": round(shade_s, 4),
        "opencv_s": round(opencv_s, 4),
        "continuous_s": round(continuous_s, 4),
    }
    return row, thumbnail, overlay_png, {"shade": shade_s, "opencv": opencv_s, "continuous": continuous_s}


def measure_case(renderer: Renderer, scene: Scene, settings: vis.MetricSettings = vis.MetricSettings()):
    """Both metrics for one scene, on its own (no sharing): ``(Visibility, Continuous)``."""
    emitter = scene.emitter
    v0 = renderer.render(scene.without_defect(), ("uv",)).uv[..., 1].copy()
    v1 = renderer.render(scene, ("uv",)).uv[..., 1].copy()
    half_width = vis.stripe_half_width(emitter, settings.threshold)
    if half_width is None:
        raise GlshadeError("measure_case: stripes wider than a third of the period need image binarisation")
    resolved = vis.resolved_mask(v0, emitter.period, settings.min_period_px) if settings.min_period_px > 0 else None
    paper = vis.paper_visibility(
        lambda p: (vis.binarize_v(v0, emitter, p, half_width), vis.binarize_v(v1, emitter, p, half_width)),
        emitter.period, settings, resolved=resolved,
    )
    return paper, vis.continuous_visibility(v0, v1, settings.keep_fraction)


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
                elif key in ("unpaired_contours", "offset_dx_px", "offset_dy_px"):
                    row[key] = int(value)
                else:
                    row[key] = float(value)
            rows.append(row)
    return rows
