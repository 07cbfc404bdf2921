"""Process-wide tuning for the commands that measure many cases (no GL here)."""

from __future__ import annotations


def reuse_freed_memory() -> None:
    """Ask glibc's allocator to keep freed memory for reuse instead of returning every
    large block to the kernel. The study allocates and frees megabytes of temporaries
    per phase; returned, each comes back as fresh pages that fault in again. Keeping them
    makes the full study about 15 % faster on the 2-core machine (docs/BENCHMARKS.md).
    Process-wide, so only the commands that measure many cases (``paper``, ``sweep``,
    ``optimize``) and Dask workers (their plugin) do it; a no-op where libc has no
    ``mallopt``."""
    import ctypes
    import ctypes.util

    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return
    m_trim_threshold, m_mmap_threshold = -1, -3
    mallopt(m_mmap_threshold, 256 << 20)  # blocks up to 256 MiB come from the heap...
    mallopt(m_trim_threshold, 1 << 30)  # ...and up to 1 GiB of freed heap is kept for reuse
