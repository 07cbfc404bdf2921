"""Case files that vouch for themselves: a finished case's JSON carries its case id and a
checksum of its content, and is trusted on reading only when both hold.

A study or a sweep resumes from its case files, so a case file is an input the next run
trusts. One edited by hand (``visibility_px = 1e308``), truncated, damaged, copied under
another case's name, or written by an older glshade without a checksum would otherwise
enter the table as if measured. :func:`read_case_file` says why such a file is not used;
the run measures that case again and says so (:func:`rejected_line`). No GL here.

The checksum is the SHA-256 of the record's canonical JSON (keys sorted, no spaces, the
case id included), so any change to a number, a key or the id breaks it. It guards
against accidents and careless edits, not against someone who recomputes it: an
integrity check, not a signature. So what a file holds is checked as well, by the store
that reads it (:meth:`glshade.instruments.record.Record.json_problem`): every field against
its column's declared type, range and words (a status from the status list, a finite
number in its unit's range, a count a non-negative int below 2**31, a text of at most
4096 characters without a control character). A forged file with a recomputed checksum
that fails that is measured again, with the same one line as a damaged one.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from glshade.errors import GlshadeError
from glshade.files import read_regular

#: The keys a case file adds to its record.
ID_KEY = "case_id"
CHECKSUM_KEY = "checksum"
#: The checksum's algorithm, as the file spells it before the hex digest.
ALGORITHM = "sha256"
#: The most bytes a case file may hold (a record is a few KiB).
MAX_CASE_FILE_BYTES = 1 << 20


def _digest(content: Mapping[str, Any]) -> str:
    canonical = json.dumps(content, sort_keys=True, separators=(",", ":"))
    return f"{ALGORITHM}:{hashlib.sha256(canonical.encode()).hexdigest()}"


def case_file_bytes(case_id: str, record: Mapping[str, Any]) -> bytes:
    """A case file's bytes: ``record`` (JSON-able) with its case id and checksum."""
    content = {ID_KEY: case_id, **record}
    content.pop(CHECKSUM_KEY, None)
    return json.dumps({**content, CHECKSUM_KEY: _digest(content)}, indent=1).encode()


@dataclass(frozen=True)
class CaseFile:
    """What reading a case file gave: its ``record`` (without the case id and checksum)
    when it is trustworthy, else None; ``problem``: why it is not used (None where the
    file is simply absent, or usable)."""

    record: dict[str, Any] | None
    problem: str | None = None


def read_case_file(path: Path, case_id: str) -> CaseFile:
    """The record of case ``case_id`` from ``path``, checked: a regular file (never a
    FIFO read), JSON, the expected case id, a checksum that matches its content."""
    if not path.exists() and not path.is_symlink():
        return CaseFile(None)
    try:
        content = json.loads(read_regular(path, "case file", MAX_CASE_FILE_BYTES))
    except GlshadeError as exc:
        return CaseFile(None, str(exc).rpartition(": ")[2])
    except (ValueError, RecursionError):
        return CaseFile(None, "is not JSON written by glshade")
    if not isinstance(content, dict):
        return CaseFile(None, "is not JSON written by glshade")
    found_id = content.get(ID_KEY)
    if found_id != case_id:
        return CaseFile(None, f"holds case {str(found_id)[:40]!r}, not {case_id!r}")
    stored = content.pop(CHECKSUM_KEY, None)
    if stored is None:
        return CaseFile(None, "has no checksum (written by an older glshade, or edited)")
    if stored != _digest(content):
        return CaseFile(None, "fails its checksum (edited or damaged)")
    content.pop(ID_KEY)
    return CaseFile(content)


class Rejected:
    """The case files a run found but could not trust, for one line saying so."""

    def __init__(self) -> None:
        self.found: list[tuple[Path, str]] = []

    def add(self, path: Path, problem: str | None) -> None:
        if problem is not None:
            self.found.append((path, problem))

    def line(self) -> str | None:
        """One line naming the files and why (the first three), or None."""
        if not self.found:
            return None
        shown = "; ".join(f"{path.name} {problem}" for path, problem in self.found[:3])
        more = f"; and {len(self.found) - 3} more" if len(self.found) > 3 else ""
        count = len(self.found)
        files = (
            "case file could not be trusted and is"
            if count == 1
            else ("case files could not be trusted and are")
        )
        return f"{count} {files} measured again: {shown}{more}"

    def say(self, notify: Callable[[str], None] | None) -> None:
        """Say :meth:`line` through ``notify`` (a warning when None)."""
        text = self.line()
        if text is None:
            return
        if notify is not None:
            notify(text)
            return
        import warnings

        from glshade.errors import GlshadeWarning

        warnings.warn(text, GlshadeWarning, stacklevel=3)
