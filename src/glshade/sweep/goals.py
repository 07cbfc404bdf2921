"""The optimiser's objectives (``glshade optimize --metric``): which record column each
reads, which instrument measures it and which way is better. Apart from
:mod:`glshade.sweep.optimize` so that the command line can list them without loading the
measuring machinery."""

from __future__ import annotations

from dataclasses import dataclass

from glshade.measure.record import COLUMNS, PMD_COLUMNS
from glshade.metrics.status import concerns

#: Every record column's unit.
_UNITS = {c.name: c.unit for c in (*COLUMNS, *PMD_COLUMNS)}


@dataclass(frozen=True)
class Goal:
    """One objective of ``--metric``: the record ``column`` it reads, the instrument
    (``method``) that measures it, ``sense`` +1 when more is better (the worst case over a
    family is the least) or -1 when less is (the worst case the most), and whether it
    needs a sensor (a number of noise: unbounded or 0 without one)."""

    name: str
    column: str
    method: str = "paper"
    sense: int = 1
    needs_sensor: bool = False

    @property
    def unit(self) -> str:
        return _UNITS[self.column]

    def unreadable(self, status: str) -> bool:
        """True when a case of ``status`` cannot give this objective: the paper metric's
        rules (:func:`glshade.metrics.status.concerns`); for phase measuring any status
        but ok (a viewpoint whose dent cannot be read is no place for the station, however
        low its noise)."""
        if self.method == "paper":
            return concerns(status, self.column)
        return status != "ok"

    def words(self) -> str:
        """How the objective reads in a line of text and on a plot's axis."""
        if self.method == "paper":
            return f"visibility ({self.name}), px"
        return f"{self.column}{f' ({self.unit})' if self.unit else ''}"


GOALS = {
    goal.name: goal
    for goal in (
        Goal("paper", "visibility_px"),
        Goal("continuous", "visibility_continuous_px"),
        Goal("pmd_snr", "pmd_snr", "pmd", needs_sensor=True),
        Goal("pmd_shift_mm", "pmd_shift_mm", "pmd"),
        Goal("pmd_depth_um", "pmd_depth_um", "pmd"),
        Goal("pmd_slope_urad", "pmd_slope_urad", "pmd"),
        Goal("pmd_noise_mm", "pmd_noise_mm", "pmd", sense=-1, needs_sensor=True),
    )
}
METRICS = tuple(GOALS)
