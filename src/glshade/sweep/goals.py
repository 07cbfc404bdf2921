"""The optimiser's objectives (``glshade optimize --metric``): every registered
instrument's :attr:`~glshade.instruments.base.Instrument.goals`, each the record column it
reads, the instrument that measures it and which way is better. Apart from
:mod:`glshade.sweep.optimize` so that the command line can list them without loading the
optimiser."""

from __future__ import annotations

from glshade.errors import GlshadeError
from glshade.instruments.base import Goal
from glshade.instruments.registry import instrument, instruments


def goals() -> dict[str, Goal]:
    """Every registered instrument's goals by name, glshade's own first."""
    return {goal.name: goal for item in instruments().by_name.values() for goal in item.goals}


def metric_names() -> tuple[str, ...]:
    """``--metric``'s choices."""
    return tuple(goals())


def goal_of(metric: str) -> Goal:
    """The goal called ``metric`` (one line listing the others when there is none)."""
    found = goals()
    if metric not in found:
        raise GlshadeError(f"--metric: must be one of {', '.join(found)}, got {metric!r}")
    return found[metric]


def unit(goal: Goal) -> str:
    """The unit of the goal's column."""
    return instrument(goal.method).column_unit(goal.column)


def unreadable(goal: Goal, status: str) -> bool:
    """True when a case of ``status`` cannot give this goal: any status but ok for a
    strict goal, else its instrument's rule
    (:meth:`~glshade.instruments.base.Instrument.concerns`)."""
    if goal.strict:
        return status != "ok"
    return instrument(goal.method).concerns(status, goal.column)


def words(goal: Goal) -> str:
    """How the goal reads in a line of text and on a plot's axis."""
    if goal.label is not None:
        return goal.label
    shown = unit(goal)
    return f"{goal.column}{f' ({shown})' if shown else ''}"
