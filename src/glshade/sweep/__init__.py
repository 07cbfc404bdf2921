"""Sweeps over any scene key, in-process or on Dask, and the viewpoint optimiser
(docs/sweeps.md)."""
