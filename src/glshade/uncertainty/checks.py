"""The budget's closed-form checks: each input with a flat mirror's first-order sensitivity
(:mod:`glshade.uncertainty.closed_forms`) against what its draws measured."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from glshade.uncertainty.closed_forms import STEP_SHARE, flat_sensitivity, has_closed_form
from glshade.uncertainty.draws import rms

if TYPE_CHECKING:
    from glshade.uncertainty.result import BudgetRun

#: What a check compares: (a draw's record key, (its name, its unit)), in the order of
#: :attr:`ClosedFormCheck.measured`.
NAMES = (
    ("slope_rms_urad", ("slope rms", "µrad")),
    ("slope_rms_tilt_removed_urad", ("slope rms, tilt removed", "µrad")),
    ("slope_dent_urad", ("slope at dent", "µrad")),
    ("shift_mm", ("shift", "mm")),
)


@dataclass(frozen=True)
class ClosedFormCheck:
    """One input's budget against its closed form at the same draws: the root mean
    square over its draws of the slope rms, the slope rms with the tilt removed, the
    slope at the dent and the dent's shift (:data:`NAMES`), as measured (``measured``)
    and as the closed form gives them for each draw's offset (``predicted``)."""

    path: str
    unit: str
    measured: tuple[float, float, float, float]
    predicted: tuple[float, float, float, float]
    sensitivity: tuple[float, float, float, float]

    def pairs(self) -> list[tuple[str, str, float, float]]:
        return [
            (name, unit, m, p)
            for (_, (name, unit)), m, p in zip(NAMES, self.measured, self.predicted, strict=True)
        ]


def closed_form_checks(run: BudgetRun) -> list[ClosedFormCheck]:
    """The closed-form check of every input of ``run`` that has one
    (:func:`has_closed_form`): the sensitivities per unit over the reference's measured
    pixels and at its dent pixel, times the root mean square of the input's drawn offsets
    (the error is linear in the offset to first order, so the contribution is
    ``|sensitivity| × rms(δ)``)."""

    ref = run.reference
    row, col = ref.get("dent_row"), ref.get("dent_col")
    checks = []
    for item in run.spec.inputs:
        if not has_closed_form(run.scene, item.path):
            continue
        pairs = [
            (draw.offsets[0][1], record)
            for draw, record in zip(run.draws, run.records, strict=True)
            if draw.input == item.path
        ]
        if not pairs or item.sigma == 0.0:
            continue
        step = STEP_SHARE * item.sigma
        sens = flat_sensitivity(run.scene, item.path, step)
        field, untilted = sens.slope_rms_urad(), sens.slope_rms_tilt_removed_urad()
        at_dent, shift = (
            sens.at(float(row), float(col))
            if row is not None and col is not None
            else (math.nan, math.nan)
        )
        spread = rms([offset for offset, _ in pairs])
        measured = [rms([record.get(key) for _, record in pairs]) for key, _ in NAMES]
        checks.append(
            ClosedFormCheck(
                item.path,
                item.unit,
                (measured[0], measured[1], measured[2], measured[3]),
                (field * spread, untilted * spread, at_dent * spread, shift * spread),
                (field, untilted, at_dent, shift),
            )
        )
    return checks
