"""A run's output directory, held for the run: a second run on it (in another process)
is refused at once with a line naming the holder (pid, host, start time, command). The
lock is an OS file lock (``filelock``): it dies with its process, so a killed run never
leaves the directory locked. ``glshade paper``, ``sweep`` and ``finding3`` all hold one."""

from __future__ import annotations

import json
import os
import socket
import time
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

from glshade.errors import GlshadeError
from glshade.files import atomic_write_bytes

LOCK_NAME = ".glshade.lock"
OWNER_NAME = ".glshade.lock.json"


@contextmanager
def run_lock(out_dir: Path, command: str = "glshade paper") -> Iterator[None]:
    """Hold ``out_dir`` (created if missing, with its ``cases/``) for the ``with`` block;
    re-entrant within a process."""
    from filelock import FileLock, Timeout

    out_dir = Path(out_dir)
    make_out_dir(out_dir)
    lock = FileLock(out_dir / LOCK_NAME, timeout=0, is_singleton=True)
    try:
        lock.acquire()
    except Timeout:
        raise GlshadeError(
            f"--out {out_dir}: in use by {_owner(out_dir)}; wait for it to finish, or choose "
            "another --out"
        ) from None
    first = lock.lock_counter == 1
    try:
        if first:
            owner = {
                "pid": os.getpid(),
                "host": socket.gethostname(),
                "command": command,
                "since": time.strftime("%Y-%m-%d %H:%M:%S"),
            }
            atomic_write_bytes(out_dir / OWNER_NAME, json.dumps(owner).encode(), "--out")
        yield
    finally:
        if first:
            with suppress(OSError):
                (out_dir / OWNER_NAME).unlink()
        lock.release()


def _owner(out_dir: Path) -> str:
    try:
        owner = json.loads((out_dir / OWNER_NAME).read_text())
        return (
            f"'{owner['command']}' (pid {owner['pid']} on {owner['host']}, since {owner['since']})"
        )
    except (OSError, ValueError, KeyError, TypeError):
        return "another glshade run"


def make_out_dir(out_dir: Path) -> None:
    """Create ``out_dir`` and its ``cases/``, or one line saying why not."""
    if "\0" in str(out_dir):
        raise GlshadeError(f"--out {str(out_dir)!r}: expected a directory path")
    if out_dir.exists() and not out_dir.is_dir():
        raise GlshadeError(f"--out {out_dir}: is not a directory")
    try:
        (out_dir / "cases").mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise GlshadeError(f"--out {out_dir}: cannot create it ({exc.strerror})") from None
    if not os.access(out_dir, os.W_OK | os.X_OK):
        raise GlshadeError(f"--out {out_dir}: not writable")
