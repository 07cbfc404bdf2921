"""Error against run time for every knob, and the stability table (``glshade accuracy``).

Every error is measured against a *converged reference* of the same scene: the fp64
shader with a root tolerance of 1e-14 mm and up to 4096 march steps (and 16x16
supersampling where the knob is supersampling), itself cross-checked against the NumPy
fp64 tracer. Three currencies:

- **uv**: largest difference of the emitter coordinates, mm, over the pixels both reach;
- **image**: largest and RMS difference of the radiance, in units of the emitter peak;
- **visibility**: difference of the defect visibility in pixels of the paper's camera.

Run time is the median wall time per frame (or per case, for the visibility knobs) over
repeats, measured in the same run. Everything is written to ``OUT/accuracy.md`` and
``OUT/figures/accuracy_*.png``; ``glshade accuracy --out docs`` regenerates the report
in the repository.
"""

from __future__ import annotations

import io
import platform
import statistics
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from glshade.files import atomic_write_bytes
from glshade.gpu.renderer import Renderer, RootSolver
from glshade.metrics import visibility as vis
from glshade.measure.single import measure_scene
from glshade.oracle import tracer as reference
from glshade.scene import Scene, paper_scene
from glshade.validation import stability

CONVERGED = RootSolver(march_steps=4096, newton_iterations=200, tolerance_mm=1e-14)
SIZE = 256


@dataclass(frozen=True)
class Point:
    """One setting of one knob: its worst error over the scenes and its median time."""

    knob: str
    label: str
    seconds: float
    errors: dict[str, float]
    default: bool = False


ALL_SURFACES = ("flat", "cylinder", "sphere")


#: The surfaces the Blinn-Phong knob is measured on (the cylinder adds nothing the two do not show).
BLINN_PHONG_SURFACES = ("flat", "sphere")


def default_scenes(size: int = SIZE, surfaces=ALL_SURFACES) -> list[tuple[str, Scene]]:
    """Paper scenes: flat, cylinder, sphere; θ 85, 45, 15, 5; a steep and a gentle dent."""
    out = []
    for surface in surfaces:
        for theta in (85.0, 45.0, 15.0, 5.0):
            for kind, sigma2, dmax in (("steep", 1.0, 0.005), ("gentle", 16.0, 0.003)):
                out.append(
                    (
                        f"{surface} θ{theta:g} {kind}",
                        paper_scene(surface, theta, sigma2, dmax).with_size(size),
                    )
                )
    return out


def _median_time(fn: Callable[[], object], repeats: int) -> tuple[float, object]:
    result, samples = None, []
    for _ in range(repeats):
        start = time.perf_counter()
        result = fn()
        samples.append(time.perf_counter() - start)
    return statistics.median(samples), result


def _uv_errors(frame, ref) -> tuple[float, float]:
    """Largest uv difference one pixel inside the mask, and on the mask's edge too (where
    a ray grazes a silhouette and the intersection is ill-conditioned)."""
    both = frame.mask & ref.mask
    if not both.any():
        return 0.0, 0.0
    inner = cv2.erode(both.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    delta = np.abs(frame.uv - ref.uv).max(axis=-1)
    return (float(delta[inner].max()) if inner.any() else 0.0), float(delta[both].max())


def _image_errors(image, ref_image, mask) -> tuple[float, float]:
    diff = np.abs(image.astype(np.float64) - ref_image)[mask]
    return (float(diff.max()), float(np.sqrt(np.mean(diff**2)))) if diff.size else (0.0, 0.0)


# --------------------------------------------------------------------------- frames
def _frame_settings() -> list[tuple[str, str, Callable[[Scene], Scene], RootSolver, bool]]:
    """Every per-frame knob: (knob, label, scene transform, root solver, is the default)."""
    settings: list[tuple[str, str, Callable[[Scene], Scene], RootSolver, bool]] = [
        ("precision", "fp32", lambda s: s, RootSolver(), True),
        (
            "precision",
            "fp64",
            lambda s: s.updated(render={"precision": "fp64"}),
            RootSolver(),
            False,
        ),
    ]
    for tol in (1e-3, 1e-5, 1e-7):
        for steps in (4, 16, 48):
            settings.append(
                (
                    "root solve",
                    f"tol {tol:g} mm, {steps} steps",
                    lambda s: s,
                    RootSolver(march_steps=steps, tolerance_mm=tol),
                    tol == 1e-7 and steps == 48,
                )
            )
    for n in (1, 2, 4, 8):
        settings.append(
            (
                "supersampling",
                f"{n}x{n}",
                lambda s, n=n: s.updated(render={"supersample": n}),
                RootSolver(),
                n == 1,
            )
        )
    return settings


def _frame_errors(knob: str, frame, ref, ref_ss) -> dict[str, float]:
    """A frame's errors against the converged references."""
    if knob == "supersampling":
        # against the supersampled reference, on the image only: a pixel's mean uv
        # is not its centre's, and the error is the averaging the setting leaves out
        peak, rms = _image_errors(frame.image, ref_ss, frame.mask | ref.mask)
        return {"pixel_image": peak, "pixel_image_rms": rms}
    peak, rms = _image_errors(frame.image, ref.image.astype(np.float64), frame.mask | ref.mask)
    errors = {"image": peak, "image_rms": rms}
    errors["uv"], errors["uv_edge"] = _uv_errors(frame, ref)
    return errors


def _oracle_gap(ref64: Scene, ref) -> float:
    """The converged reference against the NumPy tracer, in a 16x16 window at the centre."""
    rows = cols = slice(SIZE // 2 - 8, SIZE // 2 + 8)
    oracle = reference.trace(ref64, ("uv", "mask"), rows=rows, cols=cols)
    both = ref.mask[rows, cols] & oracle.mask
    return float(np.abs(ref.uv[rows, cols][both] - oracle.uv[both]).max()) if both.any() else 0.0


def frame_knobs(renderer: Renderer, scenes, repeats: int, log) -> tuple[list[Point], list[str]]:
    """Precision, root solve and supersampling: errors per frame against the converged
    reference; returns the points and the reference's cross-check lines."""
    outputs = ("image", "uv", "mask")
    converged = Renderer(renderer.context, root_solver=CONVERGED)
    settings = _frame_settings()
    worst: dict[tuple[str, str], dict[str, float]] = {}
    times: dict[tuple[str, str], list[float]] = {}
    defaults = {}
    crosscheck = []
    renderers: dict[RootSolver, Renderer] = {}
    try:
        for name, scene in scenes:
            ref64 = scene.updated(render={"precision": "fp64"})
            ref = converged.render(ref64, outputs)
            ref_ss = converged.render(
                ref64.updated(render={"supersample": 16}), ("image",)
            ).image.astype(np.float64)
            crosscheck.append(_oracle_gap(ref64, ref))
            for knob, label, transform, solver, is_default in settings:
                r = renderers.get(solver)
                if r is None:
                    r = renderers[solver] = Renderer(renderer.context, root_solver=solver)
                s = transform(scene)
                r.render(s, outputs)  # compile, warm
                seconds, frame = _median_time(lambda r=r, s=s: r.render(s, outputs), repeats)
                errors = _frame_errors(knob, frame, ref, ref_ss)
                agg = worst.setdefault((knob, label), {k: 0.0 for k in errors})
                for k, v in errors.items():
                    agg[k] = max(agg[k], v)
                times.setdefault((knob, label), []).append(seconds)
                defaults[(knob, label)] = is_default
            log(f"frames: {name}")
    finally:
        for r in renderers.values():
            r.release()
        converged.release()
    points = [
        Point(k, l, statistics.median(times[(k, l)]), worst[(k, l)], defaults[(k, l)])
        for k, l in worst
    ]
    lines = [
        (
            f"converged reference vs NumPy fp64 tracer (16x16 window at the centre of each scene): max uv gap "
            f"{max(crosscheck):.1e} mm over {len(crosscheck)} scenes"
        )
    ]
    return points, lines


# --------------------------------------------------------------------------- visibility
def visibility_knobs(renderer: Renderer, repeats: int, log, surfaces=ALL_SURFACES) -> list[Point]:
    """Resolution (256 … 2048) and phase step (1 … 0.125 mm), in paper pixels: the paper's
    metric against its continuous limit at 2048² (the truth), and the limit's own error
    at each resolution. The cases fold (σ² 1 at θ 15°) and do not."""
    cases = [paper_scene(s, t, 1.0, 0.005) for s in surfaces for t in (45.0, 15.0)]
    cases += [paper_scene(s, 45.0, 16.0, 0.003) for s in surfaces]
    settings = vis.MetricSettings()
    truth = {}
    for scene in cases:
        truth[id(scene)] = (
            measure_scene(renderer, scene.with_size(2048), settings).visibility_continuous_px
            * 1024
            / 2048
        )
    points = []
    for size in (256, 512, 1024, 2048):
        paper_err, limit_err, seconds = 0.0, 0.0, []
        for scene in cases:
            s = scene.with_size(size)
            t, result = _median_time(
                lambda s=s: measure_scene(renderer, s, settings), max(1, repeats // 2)
            )
            scale = 1024 / size
            paper_err = max(paper_err, abs(result.visibility_px * scale - truth[id(scene)]))
            limit_err = max(
                limit_err, abs(result.visibility_continuous_px * scale - truth[id(scene)])
            )
            seconds.append(t)
        points.append(
            Point(
                "resolution",
                f"{size}²",
                statistics.median(seconds),
                {"visibility": paper_err, "visibility_continuous": limit_err},
                size == 1024,
            )
        )
        log(f"visibility: resolution {size}")
    for step in (1.0, 0.5, 0.25, 0.125):
        err, seconds = 0.0, []
        metric = replace(settings, step_mm=step)
        for scene in cases:
            t, result = _median_time(
                lambda scene=scene, metric=metric: measure_scene(renderer, scene, metric), 1
            )
            err = max(err, abs(result.visibility_px - result.visibility_continuous_px))
            seconds.append(t)
        points.append(
            Point(
                "phase step",
                f"{step:g} mm",
                statistics.median(seconds),
                {"visibility": err},
                step == 0.25,
            )
        )
        log(f"visibility: phase step {step:g}")
    return points


# --------------------------------------------------------------------------- Blinn-Phong
def blinn_phong_monte_carlo(scene: Scene, samples: int, seed: int = 1) -> np.ndarray:
    """Blinn-Phong radiance by Monte-Carlo: half vectors drawn from the (n·h)^N lobe
    around the normal, l = reflect(wo, h), self-normalised weights 4 (wo·h) (the
    Jacobian from h to l); a miss of the emitter counts 0. Seeded, so reproducible."""
    rng = np.random.default_rng(seed)
    origin, directions = reference.pixel_rays(scene.camera)
    d = directions.reshape(-1, 3)
    _, points, normals, hit = reference.first_hit(scene, origin, d)
    out = np.zeros(len(d))
    n_exp = scene.render.shininess
    for i in np.nonzero(hit)[0]:
        n = normals[i]
        wo = -d[i]
        helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        e1 = np.cross(n, helper)
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(n, e1)
        u1, u2 = rng.random(samples), rng.random(samples)
        cos_t = u1 ** (1.0 / (n_exp + 1.0))  # pdf ∝ cos^N θ_h dω_h
        sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t**2))
        phi = 2 * np.pi * u2
        h = (
            (np.cos(phi) * sin_t)[:, None] * e1
            + (np.sin(phi) * sin_t)[:, None] * e2
            + cos_t[:, None] * n
        )
        wo_h = h @ wo
        l = 2 * wo_h[:, None] * h - wo
        weight = 4 * np.clip(wo_h, 0.0, None)
        _, v, valid = reference.emitter_coordinates(
            scene, np.repeat(points[i][None], samples, 0), l
        )
        radiance = np.where(valid, reference.radiance(scene.emitter, np.nan_to_num(v)), 0.0)
        out[i] = float((weight * radiance).sum() / weight.sum()) if weight.sum() > 0 else 0.0
    return out.reshape(directions.shape[:2])


#: Blinn-Phong errors are reported away from the emitter's edge too: the closed form does
#: not see a lobe that straddles it (docs/numerics.md).
EDGE_MARGIN_MM = 5.0


def blinn_phong_knob(
    renderer: Renderer, repeats: int, log, surfaces=("flat", "sphere")
) -> list[Point]:
    scenes = [
        paper_scene(s, 45.0, 4.0, 0.005)
        .with_size(24)
        .updated(render={"reflection": "blinn-phong", "shininess": 1e5})
        for s in surfaces
    ]
    truths = [reference.trace(s, ("image", "uv", "mask")) for s in scenes]
    inside = [
        t.mask
        & (
            np.nan_to_num(np.abs(t.uv), nan=np.inf).max(axis=-1)
            <= np.array(s.emitter.half_size).min() - EDGE_MARGIN_MM
        )
        for s, t in zip(scenes, truths)
    ]

    def point(label, images, seconds, default=False):
        errors = {"image": 0.0, "image_rms": 0.0, "image_edge": 0.0}
        for image, truth, away in zip(images, truths, inside):
            peak, rms = _image_errors(image, truth.image, away)
            errors["image"] = max(errors["image"], peak)
            errors["image_rms"] = max(errors["image_rms"], rms)
            errors["image_edge"] = max(
                errors["image_edge"], _image_errors(image, truth.image, truth.mask)[0]
            )
        return Point("Blinn-Phong", label, statistics.median(seconds), errors, default)

    images, seconds = [], []
    for scene in scenes:
        renderer.render(scene)
        t, image = _median_time(lambda scene=scene: renderer.render(scene).image, repeats)
        images.append(image)
        seconds.append(t)
    points = [point("closed-form lobe (GPU)", images, seconds, True)]
    for n in (16, 64, 256, 1024):
        images, seconds = [], []
        for scene in scenes:
            t, image = _median_time(lambda scene=scene, n=n: blinn_phong_monte_carlo(scene, n), 1)
            images.append(image)
            seconds.append(t)
        points.append(point(f"Monte-Carlo {n} samples (NumPy)", images, seconds))
        log(f"Blinn-Phong: Monte-Carlo {n}")
    return points


#: Microfacet lobes measured: (lobe, θ deg); roughness, the MC reference's samples per
#: pixel and the window of pixels it covers (of the 256² frame the time is taken on).
MICROFACET_CASES = (("beckmann", 30.0), ("ggx", 30.0), ("beckmann", 10.0), ("ggx", 10.0))
MICROFACET_ALPHA = 0.002
MICROFACET_REFERENCE_SAMPLES = 1 << 18


def microfacet_window(size: int) -> tuple[slice, slice]:
    """The pixels the Monte-Carlo reference covers: 8 rows x 8 columns around the dent."""
    return (
        slice(size // 2 - size // 16, size // 2 + size // 16, max(1, size // 64)),
        slice(size * 3 // 8, size * 5 // 8, max(1, size // 32)),
    )


def microfacet_knob(renderer: Renderer, repeats: int, log, size: int = SIZE) -> list[Point]:
    """How to integrate the stripes over a microfacet lobe: the closed form, the lattice
    and randomised sampling at several sample counts, against the oracle's Monte-Carlo
    (2^18 samples a pixel, 2^12 for a small test frame, on a window of 64 pixels); time per
    frame at ``size``²."""
    from glshade.oracle.tracer import _first_hit_rays, _normals

    rows, cols = microfacet_window(size)
    samples = MICROFACET_REFERENCE_SAMPLES if size >= 128 else 1 << 12
    cases = []
    for lobe, theta in MICROFACET_CASES:
        scene = (
            paper_scene("flat", theta, 4.0, 0.005)
            .with_size(size)
            .updated(render={"reflection": lobe, "roughness": MICROFACET_ALPHA})
        )
        parts = scene.active
        origins, dirs = parts.camera.sample_rays(scene, rows, cols, 1)
        o, d = np.ascontiguousarray(origins.reshape(-1, 3)), dirs.reshape(-1, 3)
        t, hit = _first_hit_rays(scene, o, d)
        p = o + t[:, None] * d
        n = _normals(scene, parts, p[:, 0], p[:, 2])
        truth, error = parts.reflection._monte_carlo(scene, p, d, n, samples, 5)
        cases.append((scene, truth, float(error.max())))
        log(
            f"microfacet: reference {lobe} theta {theta:g} (MC standard error <= {error.max():.1e})"
        )
    settings = (
        [("closed", 1, True)]
        + [("lattice", k, False) for k in (16, 64, 256, 1024)]
        + [("sampling", k, False) for k in (16, 64, 256, 1024)]
    )
    points = []
    for method, samples, default in settings:
        worst, seconds = 0.0, []
        for scene, truth, _ in cases:
            chosen = scene.updated(render={"lobe_method": method, "lobe_samples": samples})
            renderer.render(chosen)
            t, image = _median_time(lambda chosen=chosen: renderer.render(chosen).image, repeats)
            worst = max(worst, float(np.abs(image[rows, cols].ravel() - truth).max()))
            seconds.append(t)
        label = (
            "closed form (1 evaluation)" if method == "closed" else f"{method} {samples} samples"
        )
        points.append(
            Point("microfacet lobe", label, statistics.median(seconds), {"image": worst}, default)
        )
        log(f"microfacet: {label}")
    points.append(
        Point(
            "microfacet lobe",
            "reference noise (MC standard error, max)",
            float("nan"),
            {"image": max(c[2] for c in cases)},
        )
    )
    return points


#: Height-map spacings measured (mm), and the map's extent (±x, ±z mm).
MAP_SPACINGS = (1.0, 0.5, 0.25, 0.125, 0.0625)
MAP_EXTENT = (30.0, 50.0)


def heightmap_knob(
    renderer: Renderer, repeats: int, log, directory: Path, size: int = SIZE
) -> list[Point]:
    """The paper's sphere and cylinder sampled into height maps: the uv error of the
    interpolated map against the analytic surface (fp64 shader of each, on the pixels both
    hit) and the time per frame, against the spacing."""

    scenes = [
        paper_scene(kind, theta, 4.0, 0.005).with_size(size)
        for kind in ("sphere", "cylinder")
        for theta in (45.0, 15.0)
    ]
    truths = [
        renderer.render(s.updated(render={"precision": "fp64"}), ("uv", "mask")) for s in scenes
    ]
    x = np.arange(-MAP_EXTENT[0], MAP_EXTENT[0] + 1e-9, 1.0)
    points = []
    for spacing in MAP_SPACINGS:
        x = np.arange(-MAP_EXTENT[0], MAP_EXTENT[0] + 1e-9, spacing)
        z = np.arange(-MAP_EXTENT[1], MAP_EXTENT[1] + 1e-9, spacing)
        xx, zz = np.meshgrid(x, z)
        for precision in ("fp32", "fp64"):
            worst, seconds = 0.0, []
            for index, (scene, truth) in enumerate(zip(scenes, truths)):
                path = directory / f"map_{index}_{spacing:g}.npy"
                if not path.exists():
                    np.save(path, scene.active.surface.height(scene, xx, zz))
                mapped = scene.updated(
                    surface={"kind": "heightmap", "file": str(path), "spacing": (spacing, spacing)},
                    render={"precision": precision},
                )
                renderer.render(mapped, ("uv", "mask"))
                t, frame = _median_time(
                    lambda mapped=mapped: renderer.render(mapped, ("uv", "mask")), repeats
                )
                both = truth.mask & frame.mask
                worst = max(worst, float(np.abs(frame.uv - truth.uv)[both].max()))
                seconds.append(t)
            points.append(
                Point(
                    "height-map spacing",
                    f"{spacing:g} mm, {precision} ({len(x)}x{len(z)})",
                    statistics.median(seconds),
                    {"uv": worst},
                )
            )
        log(f"height map: {spacing:g} mm")
    return points


# --------------------------------------------------------------------------- report
#: Differences in time or error below this fraction are noise, not dominance.
NOISE = 0.10


def _dominates(q: Point, p: Point, currency: str) -> bool:
    qt, pt, qe, pe = q.seconds, p.seconds, q.errors[currency], p.errors[currency]
    no_worse = qt <= pt * (1 + NOISE) and qe <= pe * (1 + NOISE)
    clearly_better = qt < pt * (1 - NOISE) or qe < pe * (1 - NOISE)
    return q is not p and no_worse and clearly_better


def pareto(points: list[Point], currency: str) -> list[Point]:
    """The points no other point beats, by more than the timing noise, in time or error
    without losing in the other."""
    have = [p for p in points if currency in p.errors]
    return sorted(
        (p for p in have if not any(_dominates(q, p, currency) for q in have)),
        key=lambda p: p.seconds,
    )


def plot(points: list[Point], currency: str, title: str, unit: str, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    have = [p for p in points if currency in p.errors]
    fig, ax = plt.subplots(figsize=(7, 4.5))
    knobs = list(dict.fromkeys(p.knob for p in have))
    markers = "osD^v<>"
    floor = min((p.errors[currency] for p in have if p.errors[currency] > 0), default=1e-16)
    front = pareto(have, currency)
    labelled = {id(p) for p in front} | {id(p) for p in have if p.default}
    for knob, marker in zip(knobs, markers):
        sel = [p for p in have if p.knob == knob]
        ax.scatter(
            [p.seconds * 1e3 for p in sel],
            [max(p.errors[currency], floor / 10) for p in sel],
            marker=marker,
            s=40,
            label=knob,
        )
    for k, p in enumerate(sorted((p for p in have if id(p) in labelled), key=lambda p: p.seconds)):
        ax.annotate(
            p.label + (" (default)" if p.default else ""),
            (p.seconds * 1e3, max(p.errors[currency], floor / 10)),
            fontsize=7,
            xytext=(4, 4 + 9 * (k % 3)),
            textcoords="offset points",
        )
    ax.plot(
        [p.seconds * 1e3 for p in front],
        [max(p.errors[currency], floor / 10) for p in front],
        "k--",
        lw=1,
        label="Pareto front",
    )
    for p in have:
        if p.default:
            ax.scatter(
                [p.seconds * 1e3],
                [max(p.errors[currency], floor / 10)],
                s=160,
                facecolors="none",
                edgecolors="red",
            )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("median time per frame or case (ms)")
    ax.set_ylabel(f"worst error ({unit})")
    ax.set_title(
        title
        + "\n(red ring: shipped default; labels: the Pareto front; every setting in the table)",
        fontsize=9,
    )
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    atomic_write_bytes(path, buffer.getvalue())


def _table(points: list[Point], currencies: list[tuple[str, str]]) -> list[str]:
    head = (
        "| knob | setting | ms | "
        + " | ".join(name for _, name in currencies)
        + " | on the Pareto front |"
    )
    lines = [head, "|" + "---|" * (4 + len(currencies))]
    fronts = {c: {id(p) for p in pareto(points, c)} for c, _ in currencies}
    for p in points:
        cells = [f"{p.errors[c]:.2e}" if c in p.errors else "—" for c, _ in currencies]
        on = ", ".join(name for c, name in currencies if id(p) in fronts[c]) or "no"
        label = f"**{p.label}** (default)" if p.default else p.label
        lines.append(
            f"| {p.knob} | {label} | {p.seconds * 1e3:.1f} | " + " | ".join(cells) + f" | {on} |"
        )
    return lines


def stability_table(renderer: Renderer, log) -> tuple[list[str], dict[str, int]]:
    lines = [
        "| case | view | fp32 uv (mm) | fp64 uv (mm) | fp32 rel. distance | mask / surface mismatches | max evaluations of g | note |",
        "|---|---|---:|---:|---:|---:|---:|---|",
    ]
    histogram: dict[str, int] = {}
    for case in stability.cases():
        for view in ("centre", "field"):
            a = stability.check(renderer, case, view, "fp32")
            b = stability.check(renderer, case, view, "fp64")
            for k, count in enumerate(a.iteration_histogram):
                histogram[str(k)] = histogram.get(str(k), 0) + count
            lines.append(
                f"| {case.name} | {view} | {a.uv_error_mm:.1e} | {b.uv_error_mm:.1e} | {a.distance_error:.1e} "
                f"| {a.mask_mismatch} / {a.surface_mismatch} of {a.pixels} | {max(a.max_iterations, b.max_iterations)} | {case.note} |"
            )
        log(f"stability: {case.name}")
    return lines, histogram


def run(
    out_dir: Path, repeats: int = 5, size: int = SIZE, log=print, surfaces=ALL_SURFACES
) -> Path:
    """Measure everything and write ``out_dir/accuracy.md`` and its figures; ``surfaces``
    restricts the knobs' scenes (the stability matrix always runs whole)."""
    from glshade.errors import GlshadeError

    surfaces = tuple(surfaces)
    if not surfaces or any(s not in ALL_SURFACES for s in surfaces):
        raise GlshadeError(
            f"--scenes: must list surface kinds among {', '.join(ALL_SURFACES)}, got {', '.join(surfaces) or 'none'}"
        )
    out_dir = Path(out_dir)
    figures = out_dir / "figures"
    figures.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    with Renderer() as renderer:
        gl = renderer.context.info().renderer
        frame_points, crosscheck = frame_knobs(
            renderer, default_scenes(size, surfaces), repeats, log
        )
        vis_points = visibility_knobs(renderer, repeats, log, surfaces)
        bp_points = blinn_phong_knob(
            renderer, repeats, log, [s for s in surfaces if s in BLINN_PHONG_SURFACES] or ["flat"]
        )
        lobe_points = microfacet_knob(renderer, repeats, log, size)
        with tempfile.TemporaryDirectory() as maps:
            map_points = heightmap_knob(renderer, repeats, log, Path(maps), size)
        stab_lines, histogram = stability_table(renderer, log)
    frame_and_bp = frame_points + bp_points
    plot(
        frame_points,
        "uv",
        "uv error against time per frame",
        "mm on the emitter",
        figures / "accuracy_uv.png",
    )
    plot(
        frame_and_bp,
        "image",
        "image error against time per frame",
        "emitter peak, max",
        figures / "accuracy_image.png",
    )
    plot(
        frame_points,
        "pixel_image",
        "pixel-averaging error against time per frame (supersampling)",
        "emitter peak, max",
        figures / "accuracy_supersampling.png",
    )
    timed_lobes = [p for p in lobe_points if np.isfinite(p.seconds)]
    plot(
        timed_lobes,
        "image",
        "microfacet lobe: image error against time per frame",
        "emitter peak, max",
        figures / "accuracy_microfacet.png",
    )
    plot(
        vis_points,
        "visibility",
        "paper-metric visibility error against time per case",
        "paper px",
        figures / "accuracy_visibility.png",
    )
    plot(
        map_points,
        "uv",
        "height map: uv error against time per frame",
        "mm on the emitter",
        figures / "accuracy_heightmap.png",
    )

    lines = [
        "# Accuracy against run time, and stability",
        "",
        (
            f"Generated by `glshade accuracy --out {out_dir}` in {time.perf_counter() - started:.0f} s on "
            f"{gl} ({platform.machine()}, {repeats} repeats per timing). Method: `glshade.validation.accuracy`'s docstring."
        ),
        "",
        *_frame_section(frame_points, crosscheck, size, surfaces),
        *_visibility_section(vis_points, surfaces),
        *_blinn_phong_section(bp_points),
        *_microfacet_section(lobe_points, size),
        *_heightmap_section(map_points, size),
        "## Defaults, and why",
        "",
        *defaults_section(frame_points, vis_points, bp_points),
        "",
        *_stability_section(stab_lines, histogram),
    ]
    path = out_dir / "accuracy.md"
    atomic_write_bytes(path, ("\n".join(lines) + "\n").encode())
    return path


def _frame_section(frame_points, crosscheck, size, surfaces) -> list[str]:
    return [
        "## The converged reference",
        "",
        (
            f"fp64 shader, root tolerance 1e-14 mm, up to 4096 march steps; 16x16 supersampling for the "
            f"supersampling knob. {crosscheck[0]}."
        ),
        "",
        (
            f"## Per frame: precision, root solve, supersampling ({len(default_scenes(size, surfaces))} paper scenes at {size}²: "
            f"{', '.join(surfaces)}; θ 85, 45, 15, 5; steep σ² 1 / dmax 5 µm and gentle σ² 16 / dmax 3 µm; worst over the scenes)"
        ),
        "",
        *_table(
            frame_points,
            [
                ("uv", "uv max (mm)"),
                ("uv_edge", "uv max incl. silhouette pixels"),
                ("image", "image max"),
                ("image_rms", "image RMS"),
                ("pixel_image", "image max vs 16x16"),
                ("pixel_image_rms", "image RMS vs 16x16"),
            ],
        ),
        "",
        "![uv error against time](figures/accuracy_uv.png)",
        "",
        "![image error against time](figures/accuracy_image.png)",
        "",
        "![supersampling](figures/accuracy_supersampling.png)",
        "",
        "uv errors are over the pixels one pixel inside the mask; the next column includes the mask's edge, where",
        "a ray grazes a silhouette (docs/numerics.md). Supersampling is measured on the image against a 16x16",
        "supersampled reference: its error is the pixel-averaging the setting leaves out (the scene's content,",
        "stripe edges foremost), not arithmetic; a supersampled pixel's mean uv is not comparable with a centre",
        "sample's. The other knobs are measured against the single-sample reference.",
        "",
    ]


def _visibility_section(vis_points, surfaces) -> list[str]:
    return [
        "## Per case: resolution and phase step (visibility in pixels of the paper's 1024² camera)",
        "",
        f"{3 * len(surfaces)} cases ({', '.join(surfaces)} at θ 45 and 15 with σ² 1, dmax 5 µm; at θ 45 with σ² 16, dmax 3 µm).",
        "Resolution: against the metric's continuous limit at 2048², scaled to paper pixels (σ² 1 at θ 15 folds, so",
        "the truth there is the fold's cap, not the deflection). Phase step: the paper's metric against the limit",
        "at 1024². The paper's metric counts whole pixels of contour shift, so neither a finer step nor a larger",
        "image brings it much closer than half a pixel of the sensor: its error is quantisation. The limit is",
        "computed with sub-pixel contours and converges ("
        + " → ".join(
            f"{p.errors['visibility_continuous']:.2g}"
            for p in vis_points
            if p.knob == "resolution" and p.label != "2048²"
        )
        + " px from 256² to 1024²; docs/metric_convergence.md goes to 4096²).",
        "",
        *_table(
            vis_points,
            [
                ("visibility", "paper metric error (px)"),
                ("visibility_continuous", "continuous limit error (px)"),
            ],
        ),
        "",
        "![visibility error against time](figures/accuracy_visibility.png)",
        "",
    ]


def _blinn_phong_section(bp_points) -> list[str]:
    return [
        "## Blinn-Phong: the closed-form lobe against Monte-Carlo",
        "",
        "Against the reference's converged quadrature over the half vector (`glshade.oracle.tracer`), n = 1e5, flat",
        "and sphere at θ 45, 24x24. Monte-Carlo draws half vectors from the (n·h)^N lobe (importance sampling,",
        "self-normalised), in NumPy; the closed form runs in the shader. Errors over the pixels whose mirror ray",
        f"lands at least {EDGE_MARGIN_MM:g} mm inside the emitter, and (last column) over all: the closed form does",
        "not see a lobe that straddles the emitter's edge, which the sphere's image shows.",
        "",
        *_table(
            bp_points,
            [
                ("image", "image max"),
                ("image_rms", "image RMS"),
                ("image_edge", "image max incl. the edge"),
            ],
        ),
        "",
    ]


def _microfacet_section(lobe_points, size) -> list[str]:
    timed = [p for p in lobe_points if np.isfinite(p.seconds)]
    front = {id(p) for p in pareto(timed, "image")}
    closed = next(p for p in timed if p.default)
    noise = next(p for p in lobe_points if not np.isfinite(p.seconds)).errors["image"]
    verdict = "on the Pareto front" if id(closed) in front else "NOT on the Pareto front"
    return [
        "## Microfacet lobes: how to integrate the stripes over the lobe",
        "",
        f"Beckmann and GGX, roughness {MICROFACET_ALPHA:g}, flat plate at θ 30° and 10° (dmax 5 µm, σ² 4), against the",
        f"oracle's Monte-Carlo with {MICROFACET_REFERENCE_SAMPLES} importance samples a pixel (its standard error,",
        f"at most {noise:.1e}, is the floor below which no error is resolved) on 64 pixels around the dent; time",
        f"per {size}² frame, the median over the four scenes. The shipped default (`render.lobe_method = closed`)",
        f"is {verdict}: it costs one evaluation per ray and is more accurate than a thousand lattice samples,",
        "because the lobes that leave stripes to measure are narrow enough for `v` to be linear across them.",
        "",
        *_table(timed, [("image", "image max")]),
        "",
        "![microfacet error against time](figures/accuracy_microfacet.png)",
        "",
    ]


def _heightmap_section(map_points, size) -> list[str]:
    fp32 = [p.errors["uv"] for p in map_points if "fp32" in p.label]
    fp64 = [p.errors["uv"] for p in map_points if "fp64" in p.label]
    ratios = ", ".join(f"{a / b:.1f}" for a, b in zip(fp64, fp64[1:]))
    return [
        "## Height maps: the spacing to choose",
        "",
        (
            f"The paper's sphere and cylinder (R 70 mm) at θ 45 and 15, {size}², sampled on a ±{MAP_EXTENT[0]:g} × "
            f"±{MAP_EXTENT[1]:g} mm grid and rendered as height maps (bicubic Catmull-Rom), against the analytic surface "
            "(fp64 shader) on the pixels both hit; worst over the four scenes, median time per frame. The interpolant's "
            f"slope error falls as the spacing squared: in fp64 by {ratios} per halving. In fp32 it stops falling at "
            f"about {min(fp32):.1g} mm, the spline's float arithmetic at the grazing view (the analytic sphere's fp32 "
            "shader errs by about 1.4e-4 mm on the same pixels): below the spacing where the two meet, a finer map costs "
            "memory and buys nothing in fp32, and fp64 is the way to a closer match."
        ),
        "",
        *_table(map_points, [("uv", "uv max (mm)")]),
        "",
        "![height map error against time](figures/accuracy_heightmap.png)",
        "",
    ]


def _stability_section(stab_lines, histogram) -> list[str]:
    return [
        "## Stability on stiff and extreme cases",
        "",
        "`glshade.validation.stability.cases()`, the same matrix `tests/test_stability.py` asserts on. Centre: the central",
        "32x32 pixels of the paper's 1024² camera; field: the whole view at 48². Errors against the NumPy fp64",
        "oracle; distance errors relative, over pixels that reach the emitter; every case had no NaN or Inf",
        "inside its mask (asserted by the test).",
        "",
        *stab_lines,
        "",
        "Evaluations of g per pixel (fp32, all cases and views; count: pixels): "
        + ", ".join(f"{k}: {v}" for k, v in histogram.items() if v)
        + f". The cap is {stability.iteration_cap()}.",
        "",
        *LIMITS,
    ]


def defaults_section(frame_points, vis_points, bp_points) -> list[str]:
    out = []
    for points, currency, what in (
        (frame_points, "uv", "per frame, uv"),
        (frame_points, "image", "per frame, image"),
        (frame_points, "pixel_image", "per frame, image against 16x16 supersampling"),
        (vis_points, "visibility", "per case, paper-metric visibility"),
        (bp_points, "image", "Blinn-Phong, image"),
    ):
        front = {id(p) for p in pareto(points, currency)}
        for p in points:
            if p.default and currency in p.errors:
                where = "on the Pareto front" if id(p) in front else "not on the Pareto front"
                out.append(
                    f"- {p.knob}: **{p.label}** ({what}): {p.errors[currency]:.2e} in {p.seconds * 1e3:.1f} ms, {where}."
                )
    out += [
        "- fp32 is the default: it meets issue 2's 5e-4 mm uv goal on the paper's scenes at about 60 % of",
        "  fp64's time; fp64 is the reference, six orders of magnitude closer, for the extreme cases below.",
        "- The root solve's default (tolerance 1e-7 mm, up to 48 march steps) costs no measurable time over",
        "  looser settings (most rays converge in one or two evaluations) and buys the extreme cases.",
        "- One sample per pixel: the paper's metric works on the uv map, which supersampling averages;",
        "  supersample only images meant for looking at.",
        "- 1024² and a 0.25 mm step are the paper's; the table shows what a coarser choice costs in pixels.",
    ]
    return out


LIMITS = [
    "## Documented limits (each backed by a test)",
    "",
    "- **Silhouettes**: where a camera ray grazes a sphere or cylinder the intersection is ill-conditioned;",
    "  the fp32 uv error there reaches 5e-4 … 2e-3 mm on the mask's edge pixels (tests allow 4x the",
    "  tolerance on the edge; `test_oracle.py`, `test_stability.py`).",
    "- **Near-singular covariance** (condition 1e6: a ridge 1.4 µm wide with slope 3.5): fp32 uv error",
    "  1e-2 mm, inherent to the ridge's curvature (2500/mm) times fp32's position error; fp64 gives 8e-9 mm.",
    "- **Grazing far hits** (θ ≤ 5°, rays that meet the plane thousands of mm away and never reach the",
    "  emitter): the hit distance loses up to 1e-3 relative in fp32; no image pixel depends on it.",
    "- **Above the horizon** (θ of a few degrees): rays that go up hit nothing and are masked (uv NaN, black).",
    "- **Deep bowls** hide their bottom from low viewpoints (thin-shell occlusion, docs/numerics.md): masked.",
    "- **The march's cap** (48 steps): a ray skimming a bump for a long stretch may use them all; it then",
    "  settles for a root of the rest of its bracket. The stability matrix shows where (max evaluations).",
]
