"""Where glshade keeps, between processes, what it can check before reusing: a folder
per kind under ``GLSHADE_CACHE_DIR``, else ``$XDG_CACHE_HOME/glshade`` (by default
``~/.cache/glshade``). ``GLSHADE_CACHE_DIR=`` (empty) turns it off.

Every entry is checked against its source when it is read, so a stale one is never used,
and deleting the folder is always safe: the next process makes the entries again. Today's
one kind: ``templates``, the shader composer's compiled Jinja templates
(:mod:`glshade.gpu.template_cache`). Nothing happens at import.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

#: The environment variable that moves the cache (empty: no cache).
CACHE_ENV = "GLSHADE_CACHE_DIR"


def cache_root() -> Path | None:
    """``GLSHADE_CACHE_DIR``, else ``$XDG_CACHE_HOME/glshade`` or ``~/.cache/glshade``;
    None when the variable is set empty or no home is known."""
    given = os.environ.get(CACHE_ENV)
    if given is not None:
        return Path(given).expanduser() if given.strip() else None
    xdg = os.environ.get("XDG_CACHE_HOME", "").strip()
    if xdg:
        return Path(xdg) / "glshade"
    try:
        return Path.home() / ".cache" / "glshade"
    except RuntimeError:  # no home directory to be found
        return None


def cache_dir(kind: str) -> Path | None:
    """The folder of ``kind`` under :func:`cache_root`, made (private to the user) when
    missing; None when the cache is off, the folder cannot be made, or it is not the
    user's own and closed to others' writes (its entries are code to run)."""
    root = cache_root()
    if root is None:
        return None
    folder = root / kind
    try:
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        info = folder.stat()
    except OSError:
        return None
    if not stat.S_ISDIR(info.st_mode) or info.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        return None
    if hasattr(os, "getuid") and info.st_uid != os.getuid():
        return None
    return folder
