"""The budget's draws and what each one measures.

**Draws.** Input ``i``'s draw ``k`` believes ``true_i + σ_i z`` and the truth elsewhere;
the total's draw ``k`` believes ``true_j + σ_j z_j`` for every input ``j`` at once. Each
``z`` is a standard normal of its own stream, NumPy's ``SeedSequence(seed, spawn_key=
(kind, i, k))`` (kind 0: one input alone, 1: the total), so a draw's value depends on the
seed, its input's place in the file and its number, and on nothing else: the same file
and seed give the same draws in any order, on any worker, and adding draws keeps the
first ones.

**Numbers.** A draw is measured by phase measuring with its belief (the frames rendered
from the truth) and compared with the reference, the same scene measured believing the
truth: :func:`draw_numbers` runs where the draw was measured (the engine's ``extra``
hook, on a Dask worker too) and reduces the maps to a few numbers, so no map leaves the
worker's hook and none is stored. The reference's maps travel the other way, once per
task: :class:`Reference`.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from glshade.instruments.base import Case
from glshade.scene import Scene
from glshade.uncertainty.spec import BudgetSpec

#: A draw of one input alone, and of all inputs together (the first number of its seed's
#: spawn key).
ALONE, TOGETHER = 0, 1
#: The case key of the reference (belief = truth).
REFERENCE_KEY = "reference"
#: The kind of a draw of all inputs at once, as records and tables name it.
TOTAL = "total"


@dataclass(frozen=True)
class Draw:
    """One draw: ``input`` the path of the input drawn alone (:data:`TOTAL` for all of
    them), ``number`` its draw number, ``offsets`` the believed minus the true value of
    each input it draws (the input's unit), ``key`` its case key (a file name)."""

    input: str
    number: int
    offsets: tuple[tuple[str, float], ...]
    key: str

    def believed(self, spec: BudgetSpec) -> list[tuple[str, float]]:
        """The draw's belief: ``(path, true + offset)`` pairs (a scene's calibration)."""
        true = {item.path: item.true for item in spec.inputs}
        return [(path, true[path] + offset) for path, offset in self.offsets]


def normal(seed: int, kind: int, index: int, number: int) -> float:
    """The standard normal of stream ``(seed; kind, index, number)``."""
    sequence = np.random.SeedSequence(seed, spawn_key=(kind, index, number))
    return float(np.random.default_rng(sequence).standard_normal())


def plan_draws(spec: BudgetSpec) -> list[Draw]:
    """Every draw of ``spec``: each input's alone (in the file's order), then the total's."""
    draws = []
    for index, item in enumerate(spec.inputs):
        for number in range(spec.draws):
            offset = item.sigma * normal(spec.seed, ALONE, index, number)
            draws.append(_draw(item.path, number, ((item.path, offset),)))
    for number in range(spec.draws):
        offsets = tuple(
            (item.path, item.sigma * normal(spec.seed, TOGETHER, index, number))
            for index, item in enumerate(spec.inputs)
        )
        draws.append(_draw(TOTAL, number, offsets))
    return draws


def _draw(name: str, number: int, offsets: tuple[tuple[str, float], ...]) -> Draw:
    """A draw with its case key: the input's name as a file name, the draw number, and a
    hash of its offsets (a case file is reused only for the very same belief)."""
    slug = re.sub(r"[^A-Za-z0-9_.-]+", "_", name).strip("_") or "input"
    text = json.dumps([[path, repr(offset)] for path, offset in offsets])
    digest = hashlib.sha256(text.encode()).hexdigest()[:12]
    return Draw(name, number, offsets, f"{slug}-{number:04d}-{digest}")


def draw_cases(scene: Scene, spec: BudgetSpec, draws: list[Draw]) -> list[Case]:
    """The engine's cases of ``draws``: ``scene`` (the truth) with each draw's belief as
    its calibration; a belief the scene refuses is one line naming it
    (:meth:`~glshade.scene.Scene.with_calibration`), before anything is measured."""
    return [Case(draw.key, scene.with_calibration(draw.believed(spec))) for draw in draws]


# --------------------------------------------------------------------------- numbers
@dataclass(frozen=True)
class Reference:
    """What every draw is compared with: the reference's slope map (µrad, (H, W, 2):
    ``∂d/∂x``, ``∂d/∂z``; NaN where not measured), the true dent centre's pixel (``rows``,
    ``cols``, fractional, through the true camera), and its fitted dent (µm, mm; None
    where the fit failed)."""

    slopes_urad: np.ndarray
    dent_pixel: tuple[float, float]
    depth_um: float | None
    x0_mm: float | None
    z0_mm: float | None
    sigma_mm: float | None
    status: str
    status_reason: str

    def record(self) -> dict[str, Any]:
        """Its numbers (no map), as its case file holds them."""
        valid = np.isfinite(self.slopes_urad).all(axis=-1)
        slope = np.hypot(self.slopes_urad[..., 0], self.slopes_urad[..., 1])[valid]
        return {
            "kind": REFERENCE_KEY,
            "depth_um": self.depth_um,
            "x0_mm": self.x0_mm,
            "z0_mm": self.z0_mm,
            "sigma_mm": self.sigma_mm,
            "dent_row": _number(self.dent_pixel[0]),
            "dent_col": _number(self.dent_pixel[1]),
            "pixels": int(valid.sum()),
            "slope_rms_urad": _number(math.sqrt(float(np.mean(slope**2))) if slope.size else None),
            "status": self.status,
            "status_reason": self.status_reason,
        }


def reference_of(case: Case, result: Any, view: Any) -> Reference:
    """The engine's ``extra`` hook of the reference: its maps kept for the draws."""
    from glshade.instruments.pmd.reconstruct import project

    model = view.baseline.model
    defect, part = model.defect, model.part
    x0, z0 = np.array([float(defect.x0)]), np.array([float(defect.z0)])
    y0 = np.asarray(part.active.surface.height(part, x0, z0), np.float64)
    rows, cols = project(model, np.stack([x0, y0, z0], axis=-1))
    dent = result.maps.heights.dent
    return Reference(
        np.asarray(result.maps.slopes_urad, np.float32),
        (float(rows[0]), float(cols[0])),
        _number(dent.depth) if dent is not None else None,
        _number(dent.x0_mm) if dent is not None else None,
        _number(dent.z0_mm) if dent is not None else None,
        _number(dent.sigma_mm) if dent is not None else None,
        str(result.status),
        str(result.status_reason),
    )


def draw_numbers(reference: Reference, case: Case, result: Any, view: Any) -> dict[str, Any]:
    """The engine's ``extra`` hook of a draw: its error against ``reference`` (module doc)
    in a few numbers (JSON-able; None where a number cannot be taken):

    - ``slope_rms_urad``: the root mean square over the pixels measured in both of the
      magnitude of the slope map's error, ``|(Δ∂d/∂x, Δ∂d/∂z)|`` (µrad);
    - ``slope_rms_tilt_removed_urad``: the same of the error less its uniform tilt (each
      component's mean over those pixels: :func:`tilt_removed_rms`);
    - ``slope_dent_urad`` (and its components ``slope_dent_x_urad``, ``slope_dent_z_urad``):
      that error at the true dent centre's pixel (bilinear);
    - ``depth_um``: the fitted depth's change (µm);
    - ``shift_mm`` (``shift_x_mm``, ``shift_z_mm``): how far the fitted dent's centre moved;
    - ``pixels``: the pixels compared; ``status``/``status_reason``: the draw's own."""
    from glshade.instruments.pmd.reconstruct import sample

    error = np.asarray(result.maps.slopes_urad, np.float64) - reference.slopes_urad
    both = np.isfinite(error).all(axis=-1)
    magnitude = np.hypot(error[..., 0], error[..., 1])[both]
    untilted = tilt_removed_rms(error[both])
    rows, cols = (np.array([value]) for value in reference.dent_pixel)
    at_dent = [float(sample(error[..., axis], rows, cols)[0]) for axis in (0, 1)]
    dent = result.maps.heights.dent
    depth = shift_x = shift_z = None
    if dent is not None and reference.depth_um is not None:
        depth = float(dent.depth) - reference.depth_um
    if dent is not None and reference.x0_mm is not None and reference.z0_mm is not None:
        shift_x, shift_z = float(dent.x0_mm) - reference.x0_mm, float(dent.z0_mm) - reference.z0_mm
    return {
        "slope_rms_urad": _number(
            math.sqrt(float(np.mean(magnitude**2))) if magnitude.size else None
        ),
        "slope_rms_tilt_removed_urad": _number(untilted),
        "slope_dent_urad": _number(math.hypot(*at_dent)),
        "slope_dent_x_urad": _number(at_dent[0]),
        "slope_dent_z_urad": _number(at_dent[1]),
        "depth_um": _number(depth),
        "shift_mm": _number(
            math.hypot(shift_x, shift_z) if shift_x is not None and shift_z is not None else None
        ),
        "shift_x_mm": _number(shift_x),
        "shift_z_mm": _number(shift_z),
        "pixels": int(both.sum()),
        "status": str(result.status),
        "status_reason": str(result.status_reason),
    }


#: The numbers of a draw's record (:func:`draw_numbers`), each a finite number or None.
DRAW_NUMBERS = (
    "slope_rms_urad",
    "slope_rms_tilt_removed_urad",
    "slope_dent_urad",
    "slope_dent_x_urad",
    "slope_dent_z_urad",
    "depth_um",
    "shift_mm",
    "shift_x_mm",
    "shift_z_mm",
)
#: The numbers of the reference's record (:meth:`Reference.record`).
REFERENCE_NUMBERS = (
    "depth_um",
    "x0_mm",
    "z0_mm",
    "sigma_mm",
    "dent_row",
    "dent_col",
    "slope_rms_urad",
)


def tilt_removed_rms(slopes: np.ndarray) -> float | None:
    """The root mean square of the magnitude of ``slopes`` (N, 2: a slope map's two
    components at N pixels) less their uniform tilt, each component's mean over the N
    pixels (a plane in height is a constant slope): ``sqrt(mean(|s - mean s|²))``, the
    slope rms's convention; None for no pixel. The closed forms' is the same
    (:meth:`~glshade.uncertainty.closed_forms.FlatSensitivity.slope_rms_tilt_removed_urad`)."""
    if not len(slopes):
        return None
    rest = np.asarray(slopes, np.float64) - np.mean(slopes, axis=0, dtype=np.float64)
    return math.sqrt(float(np.mean(np.sum(rest**2, axis=-1))))


def _number(value: float | None) -> float | None:
    """A finite float, else None (JSON has no NaN)."""
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def rms(values: list[float | None]) -> float:
    """The root mean square of the numbers that are there (NaN for none)."""
    found = [float(v) for v in values if v is not None]
    return math.sqrt(sum(v * v for v in found) / len(found)) if found else math.nan
