"""Sweeps (SPEC §8.3): the sweep file, the table, resuming, Dask, the rig's azimuth and the
viewpoint optimiser.

Oracles: a case is a pure function of its scene, so the in-process table, the Dask table
and :func:`glshade.measure` must agree exactly; the paper's study's scenes are compared
key by key with the example sweep file's; the rig's azimuth against the same scene turned
by hand (a flat plate with its dent's covariance swapped, a cylinder with its axis
swapped) and against the NumPy oracle; the optimiser against synthetic objectives whose
optimum is known and a dense grid of the real objective.
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import glshade
from glshade.app.cli import main
from glshade.errors import GlshadeError
from glshade.gpu.egl_cuda import egl_cuda_numbers, egl_index_for_cuda, worker_egl_device
from glshade.instruments.record import OUTPUT_NAMES
from glshade.measure.executors import Distribution
from glshade.measure.where import open_executor
from glshade.metrics import physics
from glshade.oracle import tracer
from glshade.scene import paper_scene
from glshade.study.plan import StudyPlan
from glshade.sweep import optimize as opt
from glshade.sweep import store
from glshade.sweep.run import run_sweep
from glshade.sweep.spec import MAX_CASES_UNCONFIRMED, load_spec, spec_from_dict

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"

SMALL = {
    "size": 160,
    "grid": {
        "camera.theta_deg": [45, 15],
        "defect.sigma2": {"start": 1.0, "stop": 4.0, "num": 2},
        "surface": [
            {"label": "flat", "surface.kind": "flat"},
            {"label": "sphere", "surface.kind": "sphere", "emitter.period": 10.0},
        ],
    },
}


def small_spec(**changes):
    return spec_from_dict({**SMALL, **changes})


# ------------------------------------------------------------------ the sweep file
def test_ranges_lists_and_linked_axes():
    spec = spec_from_dict(
        {
            "grid": {
                "camera.theta_deg": {"start": 5.0, "stop": 85.0, "num": 5},
                "camera.azimuth_deg": {"start": 0.0, "stop": 90.0, "step": 30.0},
                "surface": SMALL["grid"]["surface"],
            }
        }
    )
    assert spec.count == 5 * 4 * 2
    assert [v for ((_, v),) in spec.axes[0].entries] == [5.0, 25.0, 45.0, 65.0, 85.0]
    assert [v for ((_, v),) in spec.axes[1].entries] == [0.0, 30.0, 60.0, 90.0]
    cases = spec.cases()
    last = cases[-1].scene
    assert (
        last.camera.theta_deg,
        last.camera.azimuth_deg,
        last.surface.kind,
        last.emitter.period,
    ) == (85.0, 90.0, "sphere", 10.0)
    assert spec.columns == (
        "surface",
        "camera.theta_deg",
        "camera.azimuth_deg",
        "surface.kind",
        "emitter.period",
    )
    row = spec.swept_values(cases[1])
    assert (
        row["surface"] == "sphere"
        and row["emitter.period"] == 10.0
        and row["camera.azimuth_deg"] == 0.0
    )


def test_the_issues_rig_azimuth_spelling_is_the_cameras_key():
    spec = spec_from_dict({"grid": {"rig.azimuth_deg": [0.0, 45.0]}})
    assert spec.columns == ("camera.azimuth_deg",)
    assert spec.cases()[1].scene.camera.azimuth_deg == 45.0
    (dim,) = opt.parse_over("rig.azimuth_deg=0..90")
    assert dim.key == "camera.azimuth_deg" and dim.name == "rig.azimuth_deg"
    flat = opt.search(
        lambda p: (-((p[:, 0] - 30.0) ** 2),) * 2 + ((-((p[:, 0] - 30.0) ** 2))[:, None],), (dim,)
    )
    assert set(flat.optimum) == {"rig.azimuth_deg"}


def test_case_ids_follow_the_full_scene_and_metric():
    a, b = small_spec().cases(), small_spec().cases()
    assert [c.case_id for c in a] == [c.case_id for c in b]
    assert len({c.case_id for c in a}) == len(a)
    other = spec_from_dict({**SMALL, "metric": {"step_mm": 0.5}}).cases()
    assert not {c.case_id for c in a} & {c.case_id for c in other}


@pytest.mark.parametrize(
    "data, words",
    [
        ({"grid": {"camera.theta": [5]}}, "camera.theta"),
        ({"grid": {"camera.theta_deg": []}}, "empty list"),
        ({"grid": {"camera.theta_deg": {"start": 80.0, "stop": 10.0, "num": 3}}}, "inverted"),
        ({"grid": {"camera.theta_deg": {"start": 10.0, "stop": 80.0}}}, "{start, stop, num}"),
        ({"grid": {"camera.theta_deg": [95]}}, "camera.theta_deg"),
        ({"grid": {"camera.theta_deg": [5, 5]}}, "repeat"),
        ({"grid": {}}, "at least one axis"),
        ({"grid": {"camera.theta_deg": [5]}, "extra": 1}, "unknown key 'extra'"),
        ({"grid": {"camera.theta_deg": [5]}, "metric": {"step": 1}}, "metric.step"),
        ({"grid": {"camera.theta_deg": [5], "camera.theta_deg ": [6]}}, "camera.theta_deg"),
        ({"grid": {"theta": [5]}}, "unknown key 'theta'"),
        ({"grid": {"surface": [{"label": "a"}]}}, "at least one dotted key"),
    ],
)
def test_bad_sweep_files_name_the_field(data, words):
    with pytest.raises(GlshadeError) as info:
        spec_from_dict(data)
    assert words in str(info.value) and "\n" not in str(info.value)


def test_a_big_grid_needs_yes(tmp_path, capsys):
    path = tmp_path / "big.toml"
    path.write_text(
        '[grid]\n"camera.theta_deg" = '
        f"{{ start = 1.0, stop = 89.0, num = {MAX_CASES_UNCONFIRMED + 1} }}\n"
    )
    assert main(["sweep", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "--yes" in err and str(MAX_CASES_UNCONFIRMED) in err
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------------ the table
@pytest.fixture(scope="module")
def local_table(tmp_path_factory, _session_renderer):
    out = tmp_path_factory.mktemp("sweep_local")
    result = run_sweep(small_spec(), out, renderer=_session_renderer)
    return out, result


def test_the_table_holds_every_case_and_matches_measure(local_table, renderer):
    out, result = local_table
    assert result.computed == 8 and result.skipped == 0
    rows = store.read_table(out)
    assert rows == result.rows and len(rows) == 8
    assert set(rows[0]) == {"case_id", *small_spec().columns, *OUTPUT_NAMES}
    case = small_spec().cases()[3]
    direct = glshade.measure(case.scene, renderer=renderer)
    row = next(r for r in rows if r["case_id"] == case.case_id)
    assert row["visibility_px"] == direct.visibility_px
    assert row["visibility_continuous_px"] == round(direct.visibility_continuous_px, 4)
    csv_lines = (out / "results.csv").read_text().splitlines()
    assert len(csv_lines) == 9 and csv_lines[0].startswith("case_id,surface,")
    again = run_sweep(small_spec(), out, renderer=renderer)
    assert again.computed == 0 and again.skipped == 8 and again.rows == rows


def test_the_docs_list_every_output_column():
    page = (EXAMPLES.parent / "docs" / "sweeps.md").read_text()
    missing = [name for name in OUTPUT_NAMES if f"`{name}`" not in page]
    assert not missing, f"docs/sweeps.md does not describe {missing}"


def test_a_grown_grid_reuses_the_measured_cases(local_table, renderer, tmp_path):
    out, _result = local_table
    bigger = spec_from_dict({**SMALL, "grid": {**SMALL["grid"], "camera.theta_deg": [45, 30, 15]}})
    copy = tmp_path / "grown"
    copy.mkdir()
    for path in out.rglob("*.json"):
        target = copy / path.relative_to(out)
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(path.read_bytes())
    grown = run_sweep(bigger, copy, renderer=renderer)
    assert grown.computed == 4 and grown.skipped == 8 and len(grown.rows) == 12


def test_a_changed_base_scene_is_refused_and_nothing_is_overwritten(local_table, tmp_path):
    out, _ = local_table
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    scene_file = tmp_path / "base.toml"
    paper_scene().updated(camera={"distance": 200.0}).save(scene_file)
    sweep_file = tmp_path / "sweep.toml"
    sweep_file.write_text(
        f'base = "{scene_file.name}"\nsize = 160\n[grid]\n"camera.theta_deg" = [45, 15]\n'
    )
    assert main(["sweep", str(sweep_file), "--out", str(out), "--no-progress"]) == 2
    after = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert after == before


def test_a_table_from_another_glshade_version_is_refused(local_table, tmp_path, capsys):
    import pyarrow.parquet as pq

    out, _ = local_table
    moved = tmp_path / "old"
    moved.mkdir()
    table = pq.read_table(out / "results.parquet")
    manifest = {**json.loads(table.schema.metadata[b"glshade"]), "glshade_version": "0.0.1"}
    pq.write_table(
        table.replace_schema_metadata({b"glshade": json.dumps(manifest).encode()}),
        moved / "results.parquet",
    )
    before = (moved / "results.parquet").read_bytes()
    sweep_file = tmp_path / "s.toml"
    sweep_file.write_text('size = 160\n[grid]\n"camera.theta_deg" = [45]\n')
    assert main(["sweep", str(sweep_file), "--out", str(moved), "--no-progress"]) == 2
    assert "another glshade version (0.0.1 there" in capsys.readouterr().err
    assert (moved / "results.parquet").read_bytes() == before


def test_images_on_request(tmp_path, renderer):
    spec = spec_from_dict(
        {"size": 96, "grid": {"camera.theta_deg": [45]}, "output": {"images": True}}
    )
    run_sweep(spec, tmp_path, renderer=renderer)
    (case,) = spec.cases()
    png = tmp_path / "images" / f"{case.case_id}.png"
    assert png.read_bytes()[:4] == b"\x89PNG"


def test_resume_after_kill_9(tmp_path):
    sweep_file = tmp_path / "s.toml"
    sweep_file.write_text(
        'size = 256\n[grid]\n"camera.theta_deg" = [85, 75, 65, 55, 45, 35, 25, 15]\n'
        '"defect.sigma2" = [1.0, 4.0]\n'
    )
    out = tmp_path / "out"
    process = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "glshade",
            "sweep",
            str(sweep_file),
            "--out",
            str(out),
            "--no-progress",
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(list((out / "cases").glob("*.json"))) < 3:
        time.sleep(0.05)
    os.kill(process.pid, signal.SIGKILL)
    process.wait()
    done = len(list((out / "cases").glob("*.json")))
    assert 3 <= done < 16, "the run was not killed mid-sweep"
    result = run_sweep(load_spec(sweep_file), out)
    assert result.skipped == done and result.computed == 16 - done
    ids = [row["case_id"] for row in store.read_table(out)]
    assert len(ids) == len(set(ids)) == 16


# ------------------------------------------------------------------ Dask
def test_two_local_workers_give_the_same_table(local_table, tmp_path):
    _out, result = local_table
    dask = run_sweep(small_spec(), tmp_path, Distribution(workers=2, batch=2))
    assert dask.computed == 8 and dask.rows == result.rows


def test_a_worker_killed_mid_sweep_loses_and_duplicates_nothing(local_table, tmp_path):
    from distributed import Client, LocalCluster

    _out, result = local_table
    with (
        LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None) as cluster,
        Client(cluster, set_as_default=False) as client,
    ):
        killed = []

        def kill_one(row) -> None:
            if not killed:
                pids = client.run(os.getpid)
                victim = min(pids.values())
                os.kill(victim, signal.SIGKILL)
                killed.append(victim)

        dask = run_sweep(
            small_spec(),
            tmp_path,
            Distribution(scheduler=cluster.scheduler_address, batch=1),
            on_row=kill_one,
        )
    assert killed
    assert dask.rows == result.rows
    assert len(list((tmp_path / "cases").glob("*.json"))) == 8


def test_an_unreachable_scheduler_is_one_line_within_the_timeout(tmp_path, capsys):
    sweep_file = tmp_path / "s.toml"
    sweep_file.write_text('size = 64\n[grid]\n"camera.theta_deg" = [45]\n')
    start = time.monotonic()
    code = main(
        [
            "sweep",
            str(sweep_file),
            "--out",
            str(tmp_path / "out"),
            "--scheduler",
            "tcp://127.0.0.1:9",
            "--connect-timeout",
            "2",
            "--no-progress",
        ]
    )
    assert code == 2 and time.monotonic() - start < 60
    err = capsys.readouterr().err
    assert "--scheduler tcp://127.0.0.1:9: no Dask scheduler answered within 2 s" in err
    assert err.count("\n") == 1
    assert not (tmp_path / "out" / "results.parquet").exists()


def test_egl_device_of_a_cuda_worker():
    assert egl_index_for_cuda([None, 2, 0, 1], 0) == 2
    assert egl_index_for_cuda([None, None], 0) is None
    assert (
        egl_index_for_cuda([0, 0], 0) is None
    )  # not a map: leave the choice to GLSHADE_EGL_DEVICE
    assert worker_egl_device({"CUDA_VISIBLE_DEVICES": "3", "GLSHADE_EGL_DEVICE": "1"}) is None
    assert worker_egl_device({}) is None
    numbers = egl_cuda_numbers()  # Mesa: devices, none of them a CUDA device
    assert numbers == [] or all(n is None or n >= 0 for n in numbers)


# ------------------------------------------------------------------ the paper through the sweep
def test_the_paper_study_is_one_sweep_file():
    spec = load_spec(EXAMPLES / "paper_study.toml", size=128)
    plan = StudyPlan(size=128)
    assert spec.count == len(plan.cases()) == 216
    keys = ("surface", "camera.theta_deg", "defect.sigma2", "defect.dmax")
    for case in spec.cases():
        row = spec.swept_values(case)
        assert case.scene == plan.scene(*(row[k] for k in keys))
    assert spec.settings == plan.metric


# ------------------------------------------------------------------ the rig's azimuth
def test_azimuth_turns_the_rig_over_the_dent_and_the_cylinder(renderer):
    flat = paper_scene("flat", 30.0, 4.0, 0.005).with_size(96)
    along_z = flat.updated(defect={"sigma_x2": 1.0, "sigma_z2": 4.0})
    turned = flat.updated(camera={"azimuth_deg": 90.0}, defect={"sigma_x2": 4.0, "sigma_z2": 1.0})
    a, b = renderer.render(along_z, ("uv",)).uv, renderer.render(turned, ("uv",)).uv
    assert np.nanmax(np.abs(a - b)) < 1e-4
    assert (
        np.nanmax(
            np.abs(a - renderer.render(turned.updated(camera={"azimuth_deg": 0.0}), ("uv",)).uv)
        )
        > 1e-2
    )
    cylinder = paper_scene("cylinder", 30.0, 4.0, 0.005).with_size(96)
    a = renderer.render(cylinder.updated(surface={"axis": "x"}), ("uv",)).uv
    b = renderer.render(cylinder.updated(camera={"azimuth_deg": 90.0}), ("uv",)).uv
    assert np.nanmax(np.abs(a - b)) < 1e-3


def test_azimuth_agrees_with_the_oracle(renderer):
    scene = (
        paper_scene("cylinder", 25.0, 2.0, 0.005)
        .with_size(32)
        .updated(camera={"azimuth_deg": 33.0}, defect={"x0": 0.4, "z0": -0.3})
    )
    shader, oracle = (
        renderer.render(scene, ("image", "uv", "mask")),
        tracer.trace(scene, ("image", "uv", "mask")),
    )
    assert (shader.mask == oracle.mask).all()
    assert np.nanmax(np.abs(shader.uv - oracle.uv)) < 5e-4


def test_azimuth_turns_the_closed_forms():
    cylinder = paper_scene("cylinder", 30.0, 4.0, 0.005)
    assert physics.laws(
        cylinder.updated(camera={"azimuth_deg": 90.0})
    ).magnification == pytest.approx(
        physics.laws(cylinder.updated(surface={"axis": "x"})).magnification
    )
    skew = paper_scene("flat").updated(defect={"sigma_x2": 4.0, "sigma_z2": 1.0, "sigma_xz": 0.5})
    turned = skew.updated(
        camera={"azimuth_deg": 90.0}, defect={"sigma_x2": 1.0, "sigma_z2": 4.0, "sigma_xz": -0.5}
    )
    assert physics.laws(turned).deflection_px == pytest.approx(physics.laws(skew).deflection_px)


# ------------------------------------------------------------------ the optimiser
def synthetic(peak: tuple[float, ...], quantum: float = 0.0):
    def objective(points):
        value = 10.0 - np.sum(((points - np.asarray(peak)) / 10.0) ** 2, axis=1)
        paper = np.floor(value / quantum) * quantum if quantum else value
        score = paper + opt.TIE * value if quantum else value
        return score, paper, paper[:, None]

    return objective


def test_the_optimiser_finds_a_known_optimum():
    dims = opt.parse_over("camera.theta_deg")
    result = opt.search(synthetic((37.3,)), dims)
    assert result.optimum["camera.theta_deg"] == pytest.approx(37.3, abs=0.05)
    assert result.evaluations <= 9 + 30
    two = opt.parse_over("camera.theta_deg,camera.azimuth_deg=0..90")
    result = opt.search(synthetic((61.0, 20.0)), two)
    assert result.optimum == pytest.approx(
        {"camera.theta_deg": 61.0, "camera.azimuth_deg": 20.0}, abs=0.2
    )


def test_the_refinement_copes_with_a_piecewise_constant_objective():
    """Whole-pixel plateaus: the tie-break by the continuous value still leads to the peak,
    and the reported plateau contains it."""
    result = opt.search(
        synthetic((52.0,), quantum=1.0), opt.parse_over("camera.theta_deg"), metric="paper"
    )
    assert result.visibility_px == 9.0  # floor(10 - small)
    assert abs(result.optimum["camera.theta_deg"] - 52.0) < 2.0
    lo, hi = result.near_optimal["camera.theta_deg"]
    assert lo <= 52.0 <= hi and hi - lo < 30


def test_the_optimiser_agrees_with_a_dense_grid_on_a_real_scene(renderer):
    base = paper_scene("sphere", 45.0, 4.0, 0.005).with_size(128)
    dims = (opt.Dimension("camera.theta_deg", 10.0, 80.0),)
    with open_executor(Distribution(), renderer) as executor:
        result = opt.optimize_scene(
            base,
            dims,
            [{}],
            metric="continuous",
            executor=executor,
            grid_points=8,
            refine_evaluations=12,
        )
        step = 2.5
        dense = opt.SceneObjective(
            base, dims, [{}], glshade.MetricSettings(), "continuous", executor
        )
        thetas = np.arange(10.0, 80.0 + 1e-9, step)
        _, values, _ = dense(thetas[:, None])
    best = thetas[int(np.argmax(values))]
    assert abs(result.optimum["camera.theta_deg"] - best) <= step
    assert result.visibility_px >= values.max() - 0.05 * values.max()


def test_families_and_bad_optimiser_input():
    family = opt.parse_family("defect.sigma2=1..16,defect.dmax=0.003|0.005", points=3)
    assert len(family) == 6 and family[0] == {"defect.sigma2": 1.0, "defect.dmax": 0.003}
    assert family[-1] == {"defect.sigma2": 16.0, "defect.dmax": 0.005}
    for text, words in (
        ("camera.theta_deg=80..10", "inverted"),
        ("camera.nope", "camera.nope"),
        ("surface.kind", "not a number"),
        ("emitter.period", "give its bounds"),
    ):
        with pytest.raises(GlshadeError, match=words):
            opt.parse_over(text)
    with pytest.raises(GlshadeError, match="KEY=LO..HI"):
        opt.parse_family("defect.sigma2")


def test_optimize_cli_json_and_plot(tmp_path, capsys):
    plot = tmp_path / "objective.png"
    code = main(
        [
            "optimize",
            "--over",
            "camera.theta_deg=20..60",
            "--grid",
            "3",
            "--refine",
            "4",
            "--size",
            "96",
            "--metric",
            "continuous",
            "--family",
            "defect.sigma2=1|4",
            "--json",
            "--plot",
            str(plot),
        ]
    )
    assert code == 0
    summary = json.loads(capsys.readouterr().out)
    assert set(summary) >= {"optimum", "visibility_px", "evaluations"}
    assert 20.0 <= summary["optimum"]["camera.theta_deg"] <= 60.0
    assert summary["evaluations"] >= 3 and summary["cases"] == 2 * summary["evaluations"]
    assert plot.read_bytes()[:4] == b"\x89PNG"
    assert main(["optimize", "--over", "camera.theta_deg", "--family", "defect.sigma2=4..1"]) == 2
    assert "inverted" in capsys.readouterr().err
    assert math.isfinite(summary["visibility_px"])


def test_the_optimiser_never_picks_a_view_it_cannot_read(renderer):
    """The paper's metric on a sphere with 2 mm stripes at 256²: low views leave the dent
    unresolved (0 px, status unresolved); those viewpoints are left out, counted, and the
    optimum is a view whose number can be read."""
    base = paper_scene("sphere", 45.0, 4.0, 0.005).with_size(256).updated(emitter={"period": 8})
    dims = (opt.Dimension("camera.theta_deg", 5.0, 85.0),)
    with open_executor(Distribution(), renderer) as executor:
        result = opt.optimize_scene(
            base, dims, [{}], metric="paper", executor=executor, grid_points=9,
            refine_evaluations=0,
        )  # fmt: skip
        objective = opt.SceneObjective(
            base, dims, [{}], glshade.MetricSettings(), "paper", executor
        )
        scores, values, _ = objective(result.points)
    assert result.unmeasurable > 0 and len(objective.unreadable) == result.unmeasurable
    assert np.isneginf(scores).sum() == result.unmeasurable and np.isnan(values).any()
    best = base.with_value("camera.theta_deg", result.optimum["camera.theta_deg"])
    assert glshade.measure(best, renderer=renderer).status == "ok"
    assert result.summary()["unmeasurable_cases"] == result.unmeasurable
    # nothing readable anywhere: one clear error, no optimum
    with (
        open_executor(Distribution(), renderer) as executor,
        pytest.raises(glshade.GlshadeError, match="no point of the search could be measured"),
    ):
        opt.optimize_scene(
            base.with_value("emitter.period", 2.0), dims, [{}], metric="paper",
            executor=executor, grid_points=3, refine_evaluations=0,
        )  # fmt: skip


def test_a_tampered_case_file_is_measured_again_and_said(local_table, renderer, tmp_path):
    """A case file edited by hand fails its checksum: the sweep measures that case again,
    says so once, and the table holds the measured number, not the edit."""
    out, result = local_table
    copy = tmp_path / "copy"
    for path in out.rglob("*.json"):
        target = copy / path.relative_to(out)
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(path.read_bytes())
    case = small_spec().cases()[2]
    case_file = copy / "cases" / f"{case.case_id}.json"
    data = json.loads(case_file.read_text())
    data["outputs"]["visibility_px"] = 1e308
    case_file.write_text(json.dumps(data))
    said: list[str] = []
    again = run_sweep(small_spec(), copy, renderer=renderer, notify=said.append)
    assert (again.computed, again.skipped) == (1, 7)
    assert said == [
        f"1 case file could not be trusted and is measured again: {case.case_id}.json fails "
        "its checksum (edited or damaged)"
    ]
    assert again.rows == result.rows
