"""The emitter table's selector (``[emitter]`` of a scene file): ``kind`` names the
emitter component; the emitter components' parameters join it when the scene composes its
tables (the stripes' own table is the default's)."""

from __future__ import annotations

from dataclasses import dataclass

from glshade.params import Table, param

#: The finest period an emitter may show, mm (exclusive): a nanometre. Below it the
#: stripes' half period underflows (5e-324 mm halves to 0) long before any camera could
#: see them.
MIN_PERIOD_MM = 1e-6
#: The coarsest stripe period, mm (exclusive): a thousand kilometres, a million times any
#: screen; beyond it the metric's phase count and the stripes' arithmetic overflow.
MAX_STRIPE_PERIOD_MM = 1e9


@dataclass(frozen=True)
class EmitterTable(Table):
    """The light source: ``kind`` names the emitter component."""

    table = "emitter"

    kind: str = param(
        "emitter.kind", "", "stripes", "the light source: which emitter component",
        value_type="choice", role="feature", flag="--emitter",
    )  # fmt: skip
