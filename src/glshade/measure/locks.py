"""A run's output directory, held for the run: a second run on it (in another process)
is refused at once with a line naming the holder (pid, host, start time, command). The
lock is an OS file lock (``filelock``): it dies with its process, so a killed run never
leaves the directory locked. ``glshade paper``, ``sweep`` and ``finding3`` all hold one."""

from __future__ import annotations

import json
import os
import socket
import stat
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from glshade.errors import GlshadeError
from glshade.files import (
    atomic_write_bytes,
    check_entries,
    check_inside,
    make_inside,
    read_regular,
    remove_inside,
)

LOCK_NAME = ".glshade.lock"
#: The sub-folders a run writes in (case files, a sweep's images, the PMD study's cases).
OUT_FOLDERS = ("cases", "images", "pmd_cases")
OWNER_NAME = ".glshade.lock.json"


@contextmanager
def run_lock(out_dir: Path, command: str = "glshade paper") -> Iterator[None]:
    """Hold ``out_dir`` (created if missing, with its ``cases/``) for the ``with`` block;
    re-entrant within a process."""
    from filelock import FileLock, Timeout

    out_dir = Path(out_dir)
    make_out_dir(out_dir)
    for name in (LOCK_NAME, OWNER_NAME):
        _check_lock_file(out_dir, name)
    lock = FileLock(out_dir / LOCK_NAME, timeout=0, is_singleton=True)
    try:
        lock.acquire()
    except Timeout:
        raise GlshadeError(
            f"--out {out_dir}: in use by {_owner(out_dir)}; wait for it to finish, or choose "
            "another --out"
        ) from None
    first = lock.lock_counter == 1
    wrote_owner = False
    try:
        if first:
            owner = {
                "pid": os.getpid(),
                "host": socket.gethostname(),
                "command": command,
                "since": time.strftime("%Y-%m-%d %H:%M:%S"),
            }
            atomic_write_bytes(
                out_dir / OWNER_NAME, json.dumps(owner).encode(), "--out", within=out_dir
            )
            wrote_owner = True
        yield
    finally:
        if wrote_owner:  # only what this run wrote is removed
            remove_inside(out_dir, out_dir / OWNER_NAME)
        lock.release()


def _check_lock_file(out_dir: Path, name: str) -> None:
    """The lock's files must be regular files inside ``out_dir`` (or absent): a FIFO, a
    device or a link out of the directory there is refused, and left as it is."""
    path = out_dir / name
    check_inside(out_dir, path, "--out")
    try:
        mode = path.lstat().st_mode
    except FileNotFoundError:
        return
    except OSError as exc:
        raise GlshadeError(f"--out {out_dir}: cannot use {path} ({exc.strerror})") from None
    if stat.S_ISLNK(mode):
        mode = path.stat().st_mode
    if not stat.S_ISREG(mode):
        raise GlshadeError(
            f"--out {out_dir}: {path} is not a regular file; glshade keeps its lock there: "
            "remove it or choose another --out"
        )


def _owner(out_dir: Path) -> str:
    try:
        owner = json.loads(read_regular(out_dir / OWNER_NAME, "--out", 1 << 16))
        return (
            f"'{owner['command']}' (pid {owner['pid']} on {owner['host']}, since {owner['since']})"
        )
    except (GlshadeError, OSError, ValueError, KeyError, TypeError, RecursionError):
        return "another glshade run"


def make_out_dir(out_dir: Path) -> None:
    """Create ``out_dir`` and its ``cases/``, or one line saying why not. An existing
    directory is checked first (:func:`glshade.files.check_entries`: no link out of it, no
    special file in it), so a refused run creates nothing."""
    if "\0" in str(out_dir):
        raise GlshadeError(f"--out {str(out_dir)!r}: expected a directory path")
    if out_dir.exists() and not out_dir.is_dir():
        raise GlshadeError(f"--out {out_dir}: is not a directory")
    if out_dir.is_dir():
        check_entries(out_dir, OUT_FOLDERS)
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise GlshadeError(f"--out {out_dir}: cannot create it ({exc.strerror})") from None
    if not os.access(out_dir, os.W_OK | os.X_OK):
        raise GlshadeError(f"--out {out_dir}: not writable")
    make_inside(out_dir, "cases")
