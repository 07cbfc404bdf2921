"""``glshade`` run as a user runs it: a fresh interpreter, its output captured, a hang
failing the test. Shared by the tests that check what a real process prints and leaves."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Mapping
from pathlib import Path


def run_glshade(
    *args: str, cwd: Path, env: Mapping[str, str | None] | None = None, timeout: float = 120
) -> subprocess.CompletedProcess:
    """``python -m glshade ARGS`` in ``cwd``; ``env`` adds variables to this process's
    environment (a value of None or "" removes one)."""
    environment = dict(os.environ)
    for name, value in (env or {}).items():
        if value:
            environment[name] = value
        else:
            environment.pop(name, None)
    return subprocess.run(
        [sys.executable, "-m", "glshade", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        env=environment,
        timeout=timeout,
    )
