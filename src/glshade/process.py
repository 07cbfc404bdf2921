"""Process-wide tuning for the commands that measure (no GL here)."""

from __future__ import annotations


def reuse_freed_memory() -> None:
    """Ask glibc's allocator to keep freed memory for reuse instead of returning every
    large block to the kernel. The study allocates and frees megabytes of temporaries
    per phase; returned, each comes back as fresh pages that fault in again. Keeping them
    makes the full study about 15 % faster on the 2-core machine (docs/BENCHMARKS.md).
    Process-wide, so only the commands that measure (``measure``, whose phases do the
    same on one case, ``paper``, ``sweep``, ``optimize``) and Dask workers (their plugin)
    do it; a no-op where libc has no ``mallopt``."""
    import ctypes

    try:
        mallopt = ctypes.CDLL(None).mallopt  # the C library this process already runs on
    except (OSError, AttributeError, TypeError):
        mallopt = None
    if mallopt is None:
        import ctypes.util  # finding libc by name runs ldconfig: only where the above fails

        try:
            mallopt = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6").mallopt
        except (OSError, AttributeError):
            return
    m_trim_threshold, m_mmap_threshold = -1, -3
    mallopt(m_mmap_threshold, 256 << 20)  # blocks up to 256 MiB come from the heap...
    mallopt(m_trim_threshold, 1 << 30)  # ...and up to 1 GiB of freed heap is kept for reuse
