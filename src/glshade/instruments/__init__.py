"""The instruments: what a station does with the light the renderer computes.

- :mod:`.base`: the interface every instrument implements (settings, capture and
  analysis, record, status, goals, resources);
- :mod:`.registry`: the instruments the ``glshade.instruments`` entry points name;
- :mod:`.record`: the result records, whose fields are every table's columns;
- :mod:`.stripes`: the paper's stripe-edge metric (``paper``);
- :mod:`.pmd`: phase-measuring deflectometry (``pmd``);
- :mod:`.memory`: what a case needs of the memory budget; :mod:`.figures`: their figures.
"""
