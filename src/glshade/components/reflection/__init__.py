"""The reflection slot: how the surface reflects (its selector, ``render.reflection``,
is a field of the render table). Shared here: the finish of the paper's eq. (1)
(:mod:`.finish`)."""
