"""Placeholder replaced by the Dask helper's module on merge."""


def quiet_libraries(verbose: bool = False) -> None:
    """Libraries' log output below warnings silenced unless ``verbose``."""
