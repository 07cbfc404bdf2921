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


def number_from_env(
    name: str, allowed: str, positive_only: bool, lowest: float = 0.0
) -> float | None:
    """The number in environment variable ``name`` (None when unset); a SceneError naming
    the variable when it is not one above ``lowest`` (or at least it, unless
    ``positive_only``)."""
    raw = os.environ.get(name)
    if raw is None:
        return None
    try:
        value = float(raw)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and (value > lowest if positive_only else value >= lowest)):
        raise SceneError(name, allowed, raw)
    return value


def memory_budget_from_env() -> int:
    """Bytes of the memory budget: ``GLSHADE_MEMORY_BUDGET_MB`` or 2048 MiB."""
    mib = number_from_env("GLSHADE_MEMORY_BUDGET_MB", "a number of MiB > 0", positive_only=True)
    return DEFAULT_MEMORY_BUDGET_MB << 20 if mib is None else int(mib * (1 << 20))
