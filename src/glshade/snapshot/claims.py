"""Which test checks which snapshot name, across the processes of one pytest-xdist run.

A single pytest process refuses a second check of one snapshot name in memory. Under
pytest-xdist each worker is a process of its own, so two tests of one name on two workers
would both pass and, with ``--glshade-update``, the last writer would win silently. The
controller makes one claims folder for the run and hands it to every worker
(``workerinput``); a check claims its name there with a file created exclusively (a hard
link of a file holding the test's id: it appears whole or not at all), so exactly one
test holds each name. A second test of the name fails at once, and leaves a collision
mark that fails the first too where it is still running and, at the end, the run: the
controller names both tests in one line. No GL, no NumPy here.
"""

from __future__ import annotations

import os
import uuid
from pathlib import Path

#: The key of the claims folder in a pytest-xdist worker's input.
CLAIMS_KEY = "glshade_snapshot_claims"
#: What a collision mark's name holds after the snapshot's name.
_MARK = ".collision."


def claim(folder: Path, name: str, test: str) -> str | None:
    """Claim snapshot ``name`` for ``test`` in the claims ``folder``: None where ``test``
    holds it now (or held it already), else the test that holds it (and the collision is
    marked, :func:`collisions`)."""
    path = folder / name
    draft = folder / f".{name}.{uuid.uuid4().hex}"
    draft.write_text(test)
    try:
        os.link(draft, path)  # exclusive: fails where the name is held
        return None
    except FileExistsError:
        holder = path.read_text()
        if holder == test:
            return None
        (folder / f"{name}{_MARK}{uuid.uuid4().hex}").write_text(f"{holder}\n{test}")
        return holder
    finally:
        draft.unlink()


def collided(folder: Path, name: str) -> list[str]:
    """The tests that checked snapshot ``name`` where more than one did (else [])."""
    tests: dict[str, None] = {}
    for mark in sorted(folder.glob(f"{name}{_MARK}*")):
        tests.update(dict.fromkeys(mark.read_text().splitlines()))
    return list(tests)


def collisions(folder: Path) -> dict[str, list[str]]:
    """Every snapshot name more than one test checked in the run: name -> the tests."""
    names = sorted({mark.name.split(_MARK)[0] for mark in folder.glob(f"*{_MARK}*")})
    return {name: collided(folder, name) for name in names}


def collision_line(name: str, tests: list[str]) -> str:
    """The one line that names a collision's snapshot and its tests."""
    return (
        f"snapshot name {name!r} is checked by {' and by '.join(tests)}, on two pytest-xdist "
        "workers of one run; give each check its own name"
    )
