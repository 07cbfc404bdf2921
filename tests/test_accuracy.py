"""glshade accuracy: the Pareto rule, the Monte-Carlo estimator, and a reduced run of
the command end to end."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from glshade.components.reflection.blinn_phong.accuracy import monte_carlo
from glshade.oracle import tracer as reference
from glshade.scene import paper_scene
from glshade.validation import accuracy
from glshade.validation.accuracy import Point, pareto


def test_pareto_front_ignores_noise_and_keeps_tradeoffs():
    pts = [
        Point("k", "fast, coarse", 1.0, {"e": 1e-2}),
        Point("k", "slow, fine", 10.0, {"e": 1e-6}),
        Point("k", "dominated", 12.0, {"e": 1e-3}),
        Point("k", "same as fast within noise", 1.05, {"e": 1.02e-2}),
    ]
    front = {p.label for p in pareto(pts, "e")}
    assert front == {"fast, coarse", "slow, fine", "same as fast within noise"}


def test_monte_carlo_converges_to_the_quadrature(renderer, tmp_path):
    scene = (
        paper_scene("flat", 45.0, 4.0, 0.005)
        .with_size(6)
        .updated(render={"reflection": "blinn-phong", "shininess": 1e5})
    )
    truth = reference.trace(scene, ("image", "mask"))
    bench = accuracy.Bench(renderer, 6, 1, ("flat",), tmp_path, print)
    errors = [
        np.abs(monte_carlo(bench, scene, n) - truth.image)[truth.mask].max() for n in (16, 1024)
    ]
    assert errors[1] < errors[0] and errors[1] < 0.05


@pytest.mark.slow
def test_accuracy_command_reduced(tmp_path):
    out = tmp_path / "acc"
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "glshade",
            "accuracy",
            "--out",
            str(out),
            "--repeats",
            "1",
            "--size",
            "48",
            "--scenes",
            "flat",
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    text = (out / "accuracy.md").read_text()
    for heading in (
        "## The converged reference",
        "## Per frame",
        "## Per case",
        "## Blinn-Phong",
        "## Microfacet lobes",
        "## Height maps",
        "## Defaults, and why",
        "## Stability on stiff and extreme cases",
        "## Documented limits",
    ):
        assert heading in text, heading
    assert "**fp32** (default)" in text and "on the Pareto front" in text
    for name in (
        "accuracy_uv.png",
        "accuracy_image.png",
        "accuracy_supersampling.png",
        "accuracy_visibility.png",
    ):
        assert (out / "figures" / name).stat().st_size > 1000
    # the converged reference agrees with the NumPy oracle
    gap = float(text.split("max uv gap ")[1].split(" mm")[0])
    assert gap < 1e-9


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["--scenes", "torus"], "--scenes: must list surface kinds"),
        (["--repeats", "0"], "--repeats: must be an integer >= 1"),
    ],
)
def test_accuracy_bad_input(tmp_path, args, fragment):
    result = subprocess.run(
        [sys.executable, "-m", "glshade", "accuracy", "--out", str(tmp_path / "a"), *args],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2 and fragment in result.stderr, result.stderr
