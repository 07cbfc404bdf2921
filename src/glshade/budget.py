"""The memory budget and the numbers the environment sets (``GLSHADE_MEMORY_BUDGET_MB``,
``GLSHADE_MAX_RAYS``): read here, on the ground floor, by the renderer, the measuring
floor and the height-map reader alike. No GL here."""

from __future__ import annotations

import math
import os

from glshade.errors import SceneError

#: The memory budget unless ``GLSHADE_MEMORY_BUDGET_MB`` says otherwise: a frame's buffers,
#: a measurement's analysis, a height map's loading each stay within it.
DEFAULT_MEMORY_BUDGET_MB = 2048
#: The range ``GLSHADE_MEMORY_BUDGET_MB`` may take, in MiB: from 1 MiB to 2^30 MiB (1 PiB,
#: beyond any machine's memory; in bytes 2^50, so every sum of budgets stays far inside
#: a 64-bit integer).
MEMORY_BUDGET_RANGE_MB = (1.0, float(1 << 30))


def number_from_env(
    name: str,
    allowed: str,
    positive_only: bool,
    lowest: float = 0.0,
    highest: float = math.inf,
) -> float | None:
    """The number in environment variable ``name`` (None when unset); a SceneError naming
    the variable when it is not one above ``lowest`` (or at least it, unless
    ``positive_only``) and at most ``highest``."""
    raw = os.environ.get(name)
    if raw is None:
        return None
    try:
        value = float(raw)
    except ValueError:
        value = math.nan
    above = value > lowest if positive_only else value >= lowest
    if not (math.isfinite(value) and above and value <= highest):
        raise SceneError(name, allowed, raw)
    return value


def memory_budget_from_env() -> int:
    """Bytes of the memory budget: ``GLSHADE_MEMORY_BUDGET_MB`` (a number of MiB in
    :data:`MEMORY_BUDGET_RANGE_MB`) or 2048 MiB."""
    low, high = MEMORY_BUDGET_RANGE_MB
    mib = number_from_env(
        "GLSHADE_MEMORY_BUDGET_MB",
        f"a number of MiB in [{low:g}, {high:.0f}] (2^30 MiB)",
        positive_only=False,
        lowest=low,
        highest=high,
    )
    return DEFAULT_MEMORY_BUDGET_MB << 20 if mib is None else int(mib * (1 << 20))
