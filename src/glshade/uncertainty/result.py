"""What a budget run did (:class:`BudgetRun`) and the names of its files: what the run
(:mod:`glshade.uncertainty.run`) makes and the report (:mod:`glshade.uncertainty.report`)
reads."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from glshade.scene import Scene
from glshade.uncertainty.draws import Draw
from glshade.uncertainty.spec import BudgetSpec

#: A budget's tables and figure in its output folder.
CSV = "budget.csv"
MARKDOWN = "budget.md"
FIGURE = "budget.png"
DRAWS_CSV = "draws.csv"


@dataclass
class BudgetRun:
    """What a run did: the truth ``scene`` measured, the ``spec``, the reference's record
    and every draw's (by the plan's order: :attr:`draws`, :attr:`records`), how many were
    measured now and found done, in ``seconds``, written to ``out_dir``."""

    scene: Scene
    spec: BudgetSpec
    reference: dict[str, Any]
    draws: list[Draw]
    records: list[dict[str, Any]]
    computed: int
    skipped: int
    seconds: float
    out_dir: Path
