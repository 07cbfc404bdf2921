"""glshade's own instruments, named by its ``glshade.instruments`` entry point."""

from __future__ import annotations

from glshade.instruments.base import Instrument


def builtin_instruments() -> list[Instrument]:
    """The paper's stripe metric and phase measuring."""
    from glshade.instruments.pmd import PhaseInstrument
    from glshade.instruments.stripes import StripeInstrument

    return [StripeInstrument(), PhaseInstrument()]
