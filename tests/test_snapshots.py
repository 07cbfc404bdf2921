"""Image snapshots: 128x128 renders of each surface kind at theta = 85, 45, 5.

Stored as 16-bit PNG under tests/snapshots/ and compared on the renderer that made
them (llvmpipe): per-pixel tolerance 2e-3 of the emitter peak (about half an 8-bit
level), at most 0.2 % of the pixels (32) beyond it, none beyond 0.05. Elsewhere the
oracle tests (test_oracle.py) carry the correctness checks. On failure the actual
image and a x10 magnified difference are written to tests/_failures/.
``pytest --regenerate-snapshots`` rewrites the references.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from glshade.files import read_png, write_png
from glshade.scene import paper_scene

SNAPSHOTS = Path(__file__).parent / "snapshots"
FAILURES = Path(__file__).parent / "_failures"
SIZE = 128
PIXEL_TOLERANCE = 2e-3
MAX_DIFFERING = 32
HARD_LIMIT = 0.05

CASES = [
    (surface, theta) for surface in ("flat", "cylinder", "sphere") for theta in (85.0, 45.0, 5.0)
]


@pytest.mark.parametrize("surface, theta", CASES, ids=[f"{s}-{t:g}" for s, t in CASES])
def test_snapshot(renderer, gl_context, request, surface, theta):
    name = f"{surface}_theta{theta:g}.png"
    path = SNAPSHOTS / name
    scene = paper_scene(surface, theta, 4.0, 0.005).with_size(SIZE)
    image = renderer.render(scene).image

    if request.config.getoption("--regenerate-snapshots"):
        SNAPSHOTS.mkdir(exist_ok=True)
        write_png(path, image, bits=16)
        pytest.skip(f"regenerated {name}")
    if "llvmpipe" not in gl_context.info().renderer:
        pytest.skip(
            "snapshots were made on llvmpipe; other renderers are checked against the oracle"
        )
    assert path.exists(), f"missing snapshot {path}: run pytest --regenerate-snapshots"

    reference = read_png(path).astype(np.float64) / 65535.0
    actual = np.clip(image.astype(np.float64), 0.0, 1.0)
    diff = np.abs(actual - reference)
    differing = int((diff > PIXEL_TOLERANCE).sum())
    if differing > MAX_DIFFERING or diff.max() > HARD_LIMIT:
        FAILURES.mkdir(exist_ok=True)
        write_png(FAILURES / f"actual_{name}", image, bits=16)
        write_png(FAILURES / f"diff_{name}", np.clip(diff * 10.0, 0.0, 1.0), bits=8)
        pytest.fail(
            f"{name}: {differing} pixels differ by more than {PIXEL_TOLERANCE} (cap "
            f"{MAX_DIFFERING}), "
            f"max difference {diff.max():.4f}; wrote tests/_failures/actual_{name} and diff_{name}"
        )
    # the snapshot is not blank: stripes are there
    assert reference.max() > 0.9 and (reference > 0.5).mean() > 0.05
