"""The measuring floor: every front end measures through it, one scene or many.

- :mod:`.single`: one scene (``glshade measure``, the viewer's full numbers);
- :mod:`.engine`: many scenes on one renderer, a defect-free analysis per geometry (the
  study, sweeps, the optimiser, finding 3);
- :mod:`.executors` and :mod:`.cluster`: where the cases run, this process or Dask;
- :mod:`.record`: the one result record, whose fields are every table's columns;
- :mod:`.locks`: a run's output directory, held for the run;
- :mod:`.figures`: the Fig. 9 contour overlay of a measured case.

The package is also the function ``glshade.measure(scene)``: calling it measures one
scene (:func:`glshade.measure.single.measure`).
"""

from __future__ import annotations

import sys
import types
from typing import Any


class _Callable(types.ModuleType):
    """The ``glshade.measure`` package, callable as ``glshade.measure(scene, ...)``."""

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        from glshade.measure.single import measure

        return measure(*args, **kwargs)


sys.modules[__name__].__class__ = _Callable
