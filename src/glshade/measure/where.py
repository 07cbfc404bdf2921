"""Which executor a :class:`~glshade.measure.executors.Distribution` asks for: this
process, or Dask (loaded only then)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from glshade.measure.executors import Distribution, LocalExecutor

if TYPE_CHECKING:
    from glshade.measure.cluster import DaskExecutor
    from glshade.rendering import Renderer


def open_executor(
    distribution: Distribution, renderer: Renderer | None = None
) -> LocalExecutor | DaskExecutor:
    """Where cases are measured: a :class:`LocalExecutor` or a Dask one; a context
    manager either way."""
    if distribution.on_dask:
        from glshade.measure.cluster import DaskExecutor

        return DaskExecutor(distribution)
    return LocalExecutor(distribution.threads, renderer)
