"""The shader composer's compiled templates, kept on disk between processes.

Jinja compiles each GLSL template (lexing, parsing, Python code generation) before it
renders it: for the paper's scene about 30 ms of a ``glshade measure`` process, more than
the GL compile of the program (which Mesa's own shader cache keeps). This cache keeps
that compiled code; every template is still rendered afresh, so the composed source is
the same with the cache as without it.

An entry is Python code that runs (Jinja's bucket: a pickle, then marshalled code), so
only entries this user's glshade wrote are ever read:

- The folder is held open (:class:`glshade.cache.PrivateFolder`): every entry is opened
  relative to its descriptor, never by a path, so a folder swapped or linked in after
  the ownership check is never read nor written.
- An entry is read only when it is a regular file (not a link, not a FIFO: it is opened
  without blocking), the user's own, closed to others' writes and under
  :data:`MAX_ENTRY_BYTES`; it is written to a new private file (0600) that then replaces
  it in one step.
- Every entry carries an HMAC-SHA256 of its name and content, keyed by a random 32-byte
  secret kept in the folder (``key``, private to the user, made once) joined with that
  file's identity on this file system (device, inode, change time: :func:`folder_key`);
  the HMAC is checked before any byte reaches Jinja's unpickling, so an entry made
  elsewhere (a copied or extracted folder, its key included, another user, another
  machine) is compiled again, never run, even where its owner and mode look right.

What it does not protect against: someone who can already read or write the user's
private files (the key) can run code as the user in many other ways.

When an authentic entry may be used: it is keyed by the template's name and file; it
holds the SHA-1 of the source it was compiled from and is compiled again when the file
has changed; Jinja's magic header holds its bytecode format and Python's version; the
file name holds the environment's options (delimiters, whitespace rules: the compiled
code depends on them) and Jinja's version. Any failure (a missing, damaged, forged or
unreadable entry, a full disk) means "compile again": the cache never makes composition
fail and never waits.
"""

from __future__ import annotations

import errno
import hashlib
import hmac
import os
import secrets
import stat
from collections.abc import Mapping

import jinja2
from jinja2.bccache import Bucket

from glshade.cache import PrivateFolder

#: An entry larger than this is not read (a compiled template is a few tens of kB).
MAX_ENTRY_BYTES = 4 << 20
#: The first bytes of every entry: its format (then the HMAC, then Jinja's bucket).
ENTRY_HEADER = b"glshade-template-cache-1\n"
#: The secret's file in the folder, and its length in bytes.
KEY_NAME = "key"
KEY_BYTES = 32
#: The length of an entry's HMAC-SHA256.
_MAC_BYTES = 32

#: What ``open`` says of a name it will not open as a file without following a link or
#: blocking: a symbolic link (ELOOP; EMLINK on some BSDs), a socket (ENXIO).
_NOT_A_FILE = frozenset({errno.ELOOP, errno.EMLINK, errno.ENOTDIR, errno.ENXIO})

_READ_FLAGS = (
    os.O_RDONLY
    | getattr(os, "O_NOFOLLOW", 0)
    | getattr(os, "O_NONBLOCK", 0)
    | getattr(os, "O_CLOEXEC", 0)
)
_CREATE_FLAGS = (
    os.O_WRONLY
    | os.O_CREAT
    | os.O_EXCL
    | getattr(os, "O_NOFOLLOW", 0)
    | getattr(os, "O_CLOEXEC", 0)
)


class TemplateCache(jinja2.BytecodeCache):
    """Jinja's bytecode cache in the held ``folder``, its entries named by ``options``
    (the environment's keyword arguments) and Jinja's version, each authenticated with
    the folder's secret."""

    def __init__(self, folder: PrivateFolder, options: Mapping[str, object]) -> None:
        described = repr((jinja2.__version__, sorted(options.items())))
        self._tag = hashlib.sha1(described.encode()).hexdigest()[:16]
        self._folder = folder
        self._entry_key: bytes | None = None
        self._no_key = False

    def entry_name(self, bucket: Bucket) -> str:
        """The file name of ``bucket``'s entry in the folder."""
        return f"{self._tag}-{bucket.key}.cache"

    def load_bytecode(self, bucket: Bucket) -> None:
        key = self._key()
        if key is None:
            return
        name = self.entry_name(bucket)
        try:
            data = read_private_file(self._folder.fd, name, MAX_ENTRY_BYTES)
        except OSError:
            return
        payload = None if data is None else _authentic(key, name, data)
        if payload is None:  # missing, made elsewhere, damaged, or of another format
            return
        try:
            bucket.bytecode_from_string(payload)
        except Exception:  # authentic but unreadable (a Python that changed its pickle)
            bucket.reset()

    def dump_bytecode(self, bucket: Bucket) -> None:
        key = self._key()
        if key is None or bucket.code is None:
            return
        name = self.entry_name(bucket)
        payload = bucket.bytecode_to_string()
        mac = hmac.new(key, _signed(name, payload), hashlib.sha256).digest()
        try:
            write_private_file(self._folder.fd, name, ENTRY_HEADER + mac + payload)
        except OSError:  # a full or read-only disk: the next process compiles again
            pass

    def _key(self) -> bytes | None:
        """The folder's key (:func:`folder_key`), had once; None when it cannot be."""
        if self._entry_key is None and not self._no_key:
            self._entry_key = folder_key(self._folder.fd)
            self._no_key = self._entry_key is None
        return self._entry_key


def _signed(name: str, payload: bytes) -> bytes:
    """What an entry's HMAC covers: its file name and its content."""
    return name.encode() + b"\0" + payload


def _authentic(key: bytes, name: str, data: bytes) -> bytes | None:
    """The bucket bytes of entry ``name`` when ``data`` is of this format and its HMAC is
    right (compared in constant time); None otherwise."""
    start, end = len(ENTRY_HEADER), len(ENTRY_HEADER) + _MAC_BYTES
    if not data.startswith(ENTRY_HEADER) or len(data) < end:
        return None
    mac, payload = data[start:end], data[end:]
    expected = hmac.new(key, _signed(name, payload), hashlib.sha256).digest()
    return payload if hmac.compare_digest(mac, expected) else None


def folder_key(folder_fd: int) -> bytes | None:
    """The key that authenticates the held folder's entries: an HMAC of the folder's
    secret (:data:`KEY_NAME`, :data:`KEY_BYTES` random bytes only the user may read,
    made when missing) and that file's identity on this file system (device, inode and
    change time, which no program can set: a copy of the folder, its key included, has
    another). None when the secret cannot be read or made, or is not such a secret."""
    try:
        found = _read_checked(folder_fd, KEY_NAME, KEY_BYTES, private=True)
        if found is None and not _exists(folder_fd, KEY_NAME):
            _make_secret(folder_fd)
            found = _read_checked(folder_fd, KEY_NAME, KEY_BYTES, private=True)
    except OSError:
        return None
    if found is None or len(found[0]) != KEY_BYTES:
        return None
    secret, info = found
    identity = f"{info.st_dev}:{info.st_ino}:{info.st_ctime_ns}".encode()
    return hmac.new(secret, b"glshade template cache\0" + identity, hashlib.sha256).digest()


def _exists(folder_fd: int, name: str) -> bool:
    try:
        os.stat(name, dir_fd=folder_fd, follow_symlinks=False)
    except FileNotFoundError:
        return False
    return True


def _make_secret(folder_fd: int) -> None:
    """A new secret, written whole to a temporary file and then linked in as the key
    file, so that no process ever reads a part-written one; linking never replaces a
    file, so a key another process made meanwhile stays."""
    temporary = _write_temporary(folder_fd, secrets.token_bytes(KEY_BYTES))
    try:
        os.link(
            temporary, KEY_NAME, src_dir_fd=folder_fd, dst_dir_fd=folder_fd, follow_symlinks=False
        )
    except FileExistsError:
        pass
    finally:
        _unlink_quietly(folder_fd, temporary)


def read_private_file(folder_fd: int, name: str, limit: int) -> bytes | None:
    """The bytes of file ``name`` in the held folder when it is a regular file (opened
    without following a link and without blocking), owned by the user, closed to others'
    writes and at most ``limit`` bytes; None when missing or anything else. Other
    failures raise OSError."""
    found = _read_checked(folder_fd, name, limit, private=False)
    return None if found is None else found[0]


def _read_checked(
    folder_fd: int, name: str, limit: int, private: bool
) -> tuple[bytes, os.stat_result] | None:
    """:func:`read_private_file`, closed to others' reads too when ``private``; with the
    file's status."""
    try:
        fd = os.open(name, _READ_FLAGS, dir_fd=folder_fd)
    except (FileNotFoundError, IsADirectoryError):
        return None
    except OSError as exc:
        if exc.errno in _NOT_A_FILE:
            return None
        raise
    with os.fdopen(fd, "rb", buffering=0) as file:
        info = os.fstat(fd)
        closed_to = stat.S_IRWXG | stat.S_IRWXO if private else stat.S_IWGRP | stat.S_IWOTH
        if (
            not stat.S_ISREG(info.st_mode)
            or info.st_uid != os.getuid()
            or info.st_mode & closed_to
            or info.st_size > limit
        ):
            return None
        data = file.read(limit + 1)
    return (data, info) if len(data) <= limit else None


def write_private_file(folder_fd: int, name: str, data: bytes) -> None:
    """``data`` as file ``name`` of the held folder: written to a new private file
    (0600, never through a link) that then replaces ``name`` in one step."""
    temporary = _write_temporary(folder_fd, data)
    try:
        os.replace(temporary, name, src_dir_fd=folder_fd, dst_dir_fd=folder_fd)
    except OSError:
        _unlink_quietly(folder_fd, temporary)
        raise


def _write_temporary(folder_fd: int, data: bytes) -> str:
    """A new file of the held folder holding ``data`` (private, made exclusively: never
    an existing file or link); its name."""
    name = f".tmp-{secrets.token_hex(8)}"
    fd = os.open(name, _CREATE_FLAGS, 0o600, dir_fd=folder_fd)
    try:
        with os.fdopen(fd, "wb") as file:
            file.write(data)
    except OSError:
        _unlink_quietly(folder_fd, name)
        raise
    return name


def _unlink_quietly(folder_fd: int, name: str) -> None:
    try:
        os.unlink(name, dir_fd=folder_fd)
    except OSError:
        pass
