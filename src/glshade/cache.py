"""Where glshade keeps, between processes, what it can check before reusing: a folder
per kind under ``GLSHADE_CACHE_DIR``, else ``$XDG_CACHE_HOME/glshade`` (by default
``~/.cache/glshade``). ``GLSHADE_CACHE_DIR=`` (empty) turns it off; a relative
``GLSHADE_CACHE_DIR`` (``cache``, ``./x``) turns it off too, with one warning: the folder
would move with the working directory, and a project folder could ship its own entries.

Every entry is checked against its source when it is read, so a stale one is never used,
and deleting the folder is always safe: the next process makes the entries again. Today's
one kind: ``templates``, the shader composer's compiled Jinja templates
(:mod:`glshade.gpu.template_cache`), which are code that runs. So a kind's folder is
opened once, as a descriptor (:class:`PrivateFolder`), and used only when the descriptor
shows a folder of the user's own that no one else may write to, inside a cache folder
(the root) of the same kind; every entry is then read and written relative to that
descriptor, never by its path again, so a folder renamed or swapped after the check
changes nothing. Neither the root nor a kind's folder may be a symbolic link (the root's
parents may). Where the system has no such descriptors (not POSIX) the cache is off.
Nothing happens at import.
"""

from __future__ import annotations

import os
import stat
import warnings
import weakref
from pathlib import Path

from glshade.errors import GlshadeWarning, shown_value

#: The environment variable that moves the cache (empty: no cache).
CACHE_ENV = "GLSHADE_CACHE_DIR"

#: How a folder of the cache is opened: no symbolic link as its last part, never
#: blocking (a FIFO where a folder should be), not inherited by child processes.
_FOLDER_FLAGS = (
    os.O_RDONLY
    | getattr(os, "O_DIRECTORY", 0)
    | getattr(os, "O_NOFOLLOW", 0)
    | getattr(os, "O_NONBLOCK", 0)
    | getattr(os, "O_CLOEXEC", 0)
)


def descriptors_supported() -> bool:
    """Whether this system opens files relative to a held folder descriptor without
    following links (POSIX): the cache needs it, and is off elsewhere."""
    return (
        hasattr(os, "O_NOFOLLOW")
        and hasattr(os, "O_DIRECTORY")
        and hasattr(os, "getuid")
        and {os.open, os.mkdir, os.rename, os.link, os.unlink, os.stat} <= os.supports_dir_fd
    )


def cache_root() -> Path | None:
    """``GLSHADE_CACHE_DIR`` (``~`` expanded), else ``$XDG_CACHE_HOME/glshade`` or
    ``~/.cache/glshade``; None when the variable is set empty, is a relative path (with
    one warning naming it), or no absolute home is known. A relative ``XDG_CACHE_HOME``
    is ignored, as the XDG specification asks."""
    given = os.environ.get(CACHE_ENV)
    if given is not None:
        if not given.strip():
            return None
        path = Path(given).expanduser()
        if not path.is_absolute():
            _warn_relative(given)
            return None
        return path
    xdg = os.environ.get("XDG_CACHE_HOME", "").strip()
    if xdg and Path(xdg).is_absolute():
        return Path(xdg) / "glshade"
    try:
        home = Path.home()
    except RuntimeError:  # no home directory to be found
        return None
    return home / ".cache" / "glshade" if home.is_absolute() else None


def _warn_relative(given: str) -> None:
    warnings.warn(
        f"{CACHE_ENV}={shown_value(given)} is a relative path; it must be absolute (or "
        "start with ~): glshade keeps no cache in this run",
        GlshadeWarning,
        stacklevel=2,
    )


class PrivateFolder:
    """A folder of the cache held open: ``fd``, a descriptor of a folder that was the
    user's own and closed to others' writes when it was opened; ``path``, where it was
    (for messages only: it is never opened by that path again). The descriptor is closed
    by :meth:`close` or when the object is collected."""

    def __init__(self, fd: int, path: Path) -> None:
        self.fd = fd
        self.path = path
        self._finalizer = weakref.finalize(self, os.close, fd)

    def close(self) -> None:
        self._finalizer()


def cache_dir(kind: str) -> PrivateFolder | None:
    """The folder of ``kind`` under :func:`cache_root`, held open; the root is made (with
    its parents) and the kind's folder (private to the user) when missing. None when the
    cache is off, a folder cannot be made or opened, is a symbolic link, or is not the
    user's own and closed to others' writes (its entries are code to run)."""
    root = cache_root()
    if root is None or not descriptors_supported():
        return None
    try:
        root.mkdir(mode=0o700, parents=True, exist_ok=True)
    except OSError:
        return None
    root_fd = _open_folder(str(root), None, create=False)
    if root_fd is None:
        return None
    try:
        fd = _open_folder(kind, root_fd, create=True)
    finally:
        os.close(root_fd)
    return None if fd is None else PrivateFolder(fd, root / kind)


def open_private_folder(path: Path) -> PrivateFolder | None:
    """The existing folder ``path`` held open when it is the user's own and closed to
    others' writes (not a symbolic link); None otherwise."""
    if not descriptors_supported():
        return None
    fd = _open_folder(str(path), None, create=False)
    return None if fd is None else PrivateFolder(fd, Path(path))


def _open_folder(name: str, dir_fd: int | None, create: bool) -> int | None:
    """A descriptor of folder ``name`` (relative to ``dir_fd`` when given), made private
    when missing and ``create``; None unless :func:`is_private_folder` says yes."""
    try:
        try:
            fd = os.open(name, _FOLDER_FLAGS, dir_fd=dir_fd)
        except FileNotFoundError:
            if not create:
                return None
            try:
                os.mkdir(name, 0o700, dir_fd=dir_fd)
            except FileExistsError:  # another process made it meanwhile
                pass
            fd = os.open(name, _FOLDER_FLAGS, dir_fd=dir_fd)
    except OSError:  # a symbolic link (ELOOP), not a folder, no permission
        return None
    try:
        private = is_private_folder(os.fstat(fd))
    except OSError:
        private = False
    if not private:
        os.close(fd)
        return None
    return fd


def is_private_folder(info: os.stat_result) -> bool:
    """A folder owned by this process's user that neither its group nor others may
    write to."""
    return (
        stat.S_ISDIR(info.st_mode)
        and info.st_uid == os.getuid()
        and not info.st_mode & (stat.S_IWGRP | stat.S_IWOTH)
    )
