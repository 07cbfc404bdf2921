"""The shader composer's compiled templates, kept on disk between processes.

Jinja compiles each GLSL template (lexing, parsing, Python code generation) before it
renders it: for the paper's scene about 30 ms of a ``glshade measure`` process, more than
the GL compile of the program (which Mesa's own shader cache keeps). Jinja's bytecode
cache keeps that compiled code; every template is still rendered afresh, so the composed
source is the same with the cache as without it.

When an entry may be used: it is keyed by the template's name and file; it holds the
SHA-1 of the source it was compiled from and is compiled again when the file has changed;
Jinja's magic header holds its bytecode format and Python's version; the file pattern
holds the environment's options (delimiters, whitespace rules: the compiled code depends
on them) and Jinja's version. An entry that cannot be read is compiled again, one that
cannot be written is skipped: the cache never makes composition fail.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from pathlib import Path

import jinja2
from jinja2.bccache import Bucket


class TemplateCache(jinja2.FileSystemBytecodeCache):
    """Jinja's :class:`~jinja2.FileSystemBytecodeCache` in ``directory``, its files
    named by ``options`` (the environment's keyword arguments) and Jinja's version."""

    def __init__(self, directory: Path, options: Mapping[str, object]) -> None:
        described = repr((jinja2.__version__, sorted(options.items())))
        tag = hashlib.sha1(described.encode()).hexdigest()[:16]
        super().__init__(str(directory), f"{tag}-%s.cache")

    def load_bytecode(self, bucket: Bucket) -> None:
        try:
            super().load_bytecode(bucket)
        except Exception:  # a damaged entry (Jinja checks the format, not the pickle)
            bucket.reset()

    def dump_bytecode(self, bucket: Bucket) -> None:
        try:
            super().dump_bytecode(bucket)
        except OSError:  # a full or read-only disk: the next process compiles again
            pass
