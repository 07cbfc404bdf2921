"""Writing results: atomic file replacement, PNG and TIFF images, the uv map as ``.npy``.

Every writer goes through :func:`atomic_write_bytes`: the data lands in a temporary file
in the target's directory and is renamed over the target, so an interrupted run never
leaves a half-written file behind. Outputs are only ever regular files: a path that is a
directory, a device, a FIFO or a socket is refused (:func:`check_output`), and the
front ends check every output path before any work starts.
"""

from __future__ import annotations

import contextlib
import io
import os
import stat
import tempfile
from collections.abc import Iterable, Iterator
from contextvars import ContextVar
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from glshade.errors import GlshadeError

#: Image formats by file extension (lossless only: the metric measures stripe edges).
IMAGE_SUFFIXES: dict[str, str] = {".png": ".png", ".tif": ".tiff", ".tiff": ".tiff"}
_LOSSY = frozenset({".jpg", ".jpeg", ".jpe", ".jfif", ".webp", ".avif", ".jp2", ".heic", ".heif"})
_KINDS = (
    (stat.S_ISDIR, "a directory"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISFIFO, "a FIFO"),
    (stat.S_ISSOCK, "a socket"),
)


@dataclass
class RunInputs:
    """The files one run has read as its inputs (its scene, the sweep file, a height map,
    a screen's response curve), by identity (device, inode) and resolved path: no output
    of the run is ever one of them, whatever link or name leads there. Filled as the
    readers open them (:func:`note_input`) while :func:`reading_inputs` is active."""

    identities: dict[tuple[int, int], str] = field(default_factory=dict)
    resolved: dict[str, str] = field(default_factory=dict)

    def note(self, path: str | os.PathLike[str], fd: int | None = None) -> None:
        """Record ``path`` (opened as ``fd``, when given: its identity is then that of
        what was read, not of what the name leads to now)."""
        shown = os.fspath(path)
        try:
            info = os.fstat(fd) if fd is not None else os.stat(shown)
        except OSError:
            return
        self.identities[(info.st_dev, info.st_ino)] = shown
        self.resolved[os.path.realpath(shown)] = shown

    def clash(self, target: Path) -> str | None:
        """The input (as the user named it) that writing ``target`` would replace."""
        found = self.resolved.get(os.path.realpath(target))
        if found is not None:
            return found
        try:
            info = os.stat(target)
        except OSError:
            return None
        return self.identities.get((info.st_dev, info.st_ino))


_RUN_INPUTS: ContextVar[RunInputs | None] = ContextVar("glshade_run_inputs", default=None)


@contextlib.contextmanager
def reading_inputs() -> Iterator[RunInputs]:
    """One run's record of its inputs (:class:`RunInputs`): inside, every file a reader
    notes is refused as an output by :func:`check_output` and :func:`atomic_write_bytes`.
    The command line opens one per command; outside one, nothing is recorded."""
    inputs = RunInputs()
    token = _RUN_INPUTS.set(inputs)
    try:
        yield inputs
    finally:
        _RUN_INPUTS.reset(token)


def note_input(path: str | os.PathLike[str], fd: int | None = None) -> None:
    """Record ``path`` as an input of the current run (:func:`reading_inputs`), if any."""
    inputs = _RUN_INPUTS.get()
    if inputs is not None:
        inputs.note(path, fd)


def special_kind(mode: int) -> str | None:
    """What a file of ``mode`` is when it is not a regular file (``"a FIFO"``), else
    None."""
    if stat.S_ISREG(mode):
        return None
    return next((name for test, name in _KINDS if test(mode)), "not a regular file")


def check_output(
    path: str | os.PathLike[str],
    what: str = "output",
    suffixes: tuple[str, ...] = (),
    *,
    inputs: Iterable[str | os.PathLike[str]] = (),
    probe: bool = True,
) -> Path:
    """The regular file ``path`` will be written as (a symbolic link the user named is
    written through), or a :class:`GlshadeError` naming ``what`` (a flag such as ``-o``)
    and why not: an existing directory, device, FIFO or socket, a missing or unwritable
    directory, an extension not in ``suffixes`` (lower case, with the dot; empty: any), or
    one of the run's ``inputs`` (its scene, height map, sweep file: never overwritten).

    ``probe``: prove the directory writable by creating (and removing) a file there, as
    the write will; ``os.access`` answers yes for root even where nothing can be created
    (``/proc``)."""
    text = os.fspath(path)
    if not text or text.endswith(os.sep) or "\0" in text:
        raise GlshadeError(f"{what} {text!r}: expected a file path")
    target = Path(os.path.realpath(text))
    mode = _mode(target, what, text)
    kind = None if mode is None else special_kind(mode)
    if kind is not None:
        raise GlshadeError(f"{what} {text}: is {kind}; glshade only writes regular files")
    if suffixes and target.suffix.lower() not in suffixes:
        raise GlshadeError(f"{what} {text}: {_suffix_problem(target.suffix.lower(), suffixes)}")
    shown = os.path.dirname(text) or "."
    if not target.parent.is_dir():
        raise GlshadeError(f"{what} {text}: directory {shown} does not exist")
    if not os.access(target.parent, os.W_OK | os.X_OK):
        raise GlshadeError(f"{what} {text}: directory {shown} is not writable")
    _refuse_input(target, what, text, inputs)
    if probe:
        probe_directory(target.parent, what, text)
    return target


def _refuse_input(
    target: Path, what: str, text: str, inputs: Iterable[str | os.PathLike[str]]
) -> None:
    """One line if writing ``target`` would replace one of ``inputs`` or a file the
    current run has read as an input (:func:`reading_inputs`)."""
    recorded = _RUN_INPUTS.get()
    found = recorded.clash(target) if recorded is not None else None
    found = found or next((os.fspath(s) for s in inputs if _same_file(target, s)), None)
    if found is not None:
        raise GlshadeError(
            f"{what} {text}: is one of this run's inputs ({found}); glshade never writes "
            "over its inputs: choose another path"
        )


def _mode(target: Path, what: str, text: str) -> int | None:
    """``target``'s file type and mode (None: it does not exist yet)."""
    try:
        return target.stat().st_mode
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise GlshadeError(f"{what} {text}: cannot use it ({exc.strerror})") from None


def _same_file(target: Path, source: str | os.PathLike[str]) -> bool:
    """Whether writing ``target`` would replace the file ``source`` (by its resolved path,
    or the same inode through a hard link)."""
    resolved = Path(os.path.realpath(os.fspath(source)))
    if resolved == target:
        return True
    try:
        return os.path.samefile(target, resolved)
    except OSError:
        return False


def probe_directory(directory: Path, what: str, text: str, shown: str | None = None) -> None:
    """Create and remove a file in ``directory``, or one line naming ``what`` and ``text``
    (the output as the user typed it; ``shown``: the directory as they typed it, by
    default ``text``'s) saying why it cannot be written (read-only mount, a pseudo file
    system such as ``/proc``, no space for a new entry)."""
    try:
        fd, probe = tempfile.mkstemp(prefix=".glshade-probe.", dir=directory)
    except OSError as exc:
        shown = shown or os.path.dirname(text) or "."
        raise GlshadeError(
            f"{what} {text}: cannot write in {shown} ({exc.strerror or exc})"
        ) from None
    os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(probe)


def check_inside(root: str | os.PathLike[str], path: str | os.PathLike[str], what: str) -> Path:
    """``path``, a file glshade names inside the output directory ``root`` (a case file,
    a figure, the report), checked to stay there: resolved (every symbolic link followed),
    it must lie inside ``root`` resolved. A link that leads out (a ``cases/`` linked to a
    folder elsewhere, a ``report.md`` linked to a file outside) is refused with one line,
    so a run never writes or removes anything outside the directory the user named."""
    base = Path(os.path.realpath(os.fspath(root)))
    resolved = Path(os.path.realpath(os.fspath(path)))
    if resolved != base and base not in resolved.parents:
        link = _first_link(Path(root), Path(path))
        shown = (
            f"{link} is a link to {os.readlink(link)}"
            if link is not None
            else f"{path} resolves to {resolved}"
        )
        raise GlshadeError(
            f"{what} {root}: {shown}, outside the output directory; glshade writes only inside "
            "it: remove the link or choose another directory"
        )
    return resolved


def refuse_link(root: str | os.PathLike[str], path: str | os.PathLike[str], what: str) -> None:
    """One line if ``path``, a file glshade names inside the output directory ``root``, is
    a symbolic link: written through, it would replace the file it leads to (a sibling,
    one of the run's inputs) instead of glshade's own."""
    if os.path.islink(path):
        raise GlshadeError(
            f"{what} {root}: {path} is a symbolic link (to {os.readlink(path)}); glshade "
            "writes its own files there, never through a link: remove it"
        )


def make_inside(root: Path, name: str, what: str = "--out") -> Path:
    """The folder ``root/name`` (``cases``, ``images``), made when missing, checked to be a
    directory inside ``root`` (:func:`check_inside`: never a link to a folder elsewhere)."""
    folder = Path(root) / name
    check_inside(root, folder, what)
    try:
        folder.mkdir(exist_ok=True)
    except FileExistsError:
        raise GlshadeError(f"{what} {root}: {folder} is not a directory") from None
    except OSError as exc:
        raise GlshadeError(f"{what} {root}: cannot create {folder} ({exc.strerror})") from None
    check_inside(root, folder, what)
    return folder


def check_entries(root: Path, folders: tuple[str, ...] = (), what: str = "--out") -> None:
    """Before a run writes into the output directory ``root``: every entry in it (and in
    its sub-folders ``folders``) is a regular file or a folder inside it. A symbolic link
    that leads out of ``root`` or to a file (a sibling the run would replace through it),
    or a FIFO, device or socket (which a reader would wait on forever, and a writer must
    not replace), is refused with one line naming it, before any work and before anything
    is written."""
    for folder in (Path(root), *(Path(root) / name for name in folders)):
        if folder != Path(root) and not folder.is_dir():
            continue
        try:
            entries = list(os.scandir(folder))
        except OSError as exc:
            raise GlshadeError(f"{what} {root}: cannot list {folder} ({exc.strerror})") from None
        for entry in entries:
            path = Path(entry.path)
            if entry.is_symlink():
                check_inside(root, path, what)
                if not path.is_dir():  # written through, it would replace its sibling
                    refuse_link(root, path, what)
            mode = _mode(path, what, entry.path) if os.path.lexists(path) else None
            kind = None if mode is None or stat.S_ISDIR(mode) else special_kind(mode)
            if kind is not None:
                raise GlshadeError(
                    f"{what} {root}: {path} is {kind}; glshade keeps only regular files "
                    "there: remove it or choose another directory"
                )


def _first_link(root: Path, path: Path) -> Path | None:
    """The first component of ``path`` below ``root`` that is a symbolic link."""
    try:
        parts = path.relative_to(root).parts
    except ValueError:
        return None
    current = root
    for part in parts:
        current = current / part
        if current.is_symlink():
            return current
    return None


def _suffix_problem(suffix: str, suffixes: tuple[str, ...]) -> str:
    allowed = ", ".join(suffixes)
    if suffix in _LOSSY:
        return (
            f"{suffix} is a lossy format, which would blur the stripe edges; use one of {allowed}"
        )
    return f"the extension {suffix or '(none)'} is not supported; use one of {allowed}"


def atomic_write_bytes(
    path: Path,
    data: bytes,
    what: str = "output",
    within: Path | None = None,
    *,
    flush: bool = True,
) -> None:
    """Write ``data`` to ``path`` atomically (temp file + ``os.replace``); only ever a
    regular file (see :func:`check_output`). ``within``: the output directory the file
    belongs to (a file glshade names there), which it must not leave through a link
    (:func:`check_inside`); None: a file the user named (a link to a regular file is
    written through). ``flush``: the data reaches the disk (``fsync``) before the rename;
    False leaves that to :func:`flush_files`, once for a group of files (the name still
    never shows a partly written file to this or another process)."""
    if within is not None:
        check_inside(within, path, what)
        refuse_link(within, path, what)
    target = check_output(path, what, probe=False)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    except OSError as exc:
        raise GlshadeError(f"{what} {path}: cannot write here ({exc.strerror})") from None
    try:
        os.fchmod(fd, 0o666 & ~_umask())  # mkstemp makes 0600; a plain open() honours the umask
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            if flush:
                fh.flush()
                os.fsync(fh.fileno())
        os.replace(tmp, target)
    except BaseException as exc:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(exc, OSError):
            raise GlshadeError(f"{what} {path}: cannot write it ({exc.strerror or exc})") from None
        raise


def flush_files(paths: Iterable[str | os.PathLike[str]], what: str = "output") -> None:
    """Make files written with ``atomic_write_bytes(..., flush=False)`` durable as a group:
    each file's data (``fsync``), then each of their folders once (the renames). A file
    that is gone meanwhile is skipped; a failure is one line naming ``what``."""
    folders: dict[str, None] = {}
    for path in paths:
        text = os.fspath(path)
        with contextlib.suppress(FileNotFoundError):
            _fsync_path(text, os.O_RDONLY | os.O_NONBLOCK, what)
        folders[os.path.dirname(os.path.abspath(text))] = None
    for folder in folders:
        _fsync_path(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0), what)


def _fsync_path(path: str, flags: int, what: str) -> None:
    try:
        fd = os.open(path, flags | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise
    except OSError as exc:
        raise GlshadeError(f"{what} {path}: cannot write it ({exc.strerror or exc})") from None
    try:
        os.fsync(fd)
    except OSError as exc:
        raise GlshadeError(f"{what} {path}: cannot write it ({exc.strerror or exc})") from None
    finally:
        os.close(fd)


def remove_inside(root: Path, path: Path) -> bool:
    """Remove the regular file ``path`` inside the output directory ``root`` (the files a
    rerun with ``--overwrite`` replaces); a path that leads out of ``root`` through a link,
    or that is not a regular file, is left alone. Returns whether it was removed."""
    try:
        check_inside(root, path, "--out")
    except GlshadeError:
        return False
    if path.is_symlink() or not path.is_file():
        return False
    path.unlink()
    return True


#: The most bytes :func:`read_regular` reads unless told otherwise (a case file, a
#: manifest: a few KiB).
MAX_RECORD_BYTES = 16 << 20
#: The most bytes a results table glshade reads back may hold (a study's CSV is a few KiB
#: a case).
RESULTS_TABLE_BYTES = 1 << 30


def open_regular(path: str | os.PathLike[str], what: str) -> int:
    """A read-only descriptor of the regular file ``path``, or one line saying what it is
    instead. The file is opened without blocking (a FIFO or a device would wait for a
    writer forever) and its type checked on the open descriptor; the descriptor then
    blocks as usual. The caller closes it."""
    text = os.fspath(path)
    try:
        kind = special_kind(os.stat(text).st_mode)  # before opening: opening a device acts
        if kind is not None:
            raise GlshadeError(f"{what} {text}: is {kind}; glshade reads only regular files")
        fd = os.open(text, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise GlshadeError(f"{what} {text}: does not exist") from None
    except IsADirectoryError:
        raise GlshadeError(f"{what} {text}: is a directory, not a file") from None
    except OSError as exc:
        raise GlshadeError(f"{what} {text}: cannot read it ({exc.strerror or exc})") from None
    except ValueError:  # a NUL byte in the path
        raise GlshadeError(f"{what} {text!r}: expected a path without NUL bytes") from None
    kind = special_kind(os.fstat(fd).st_mode)  # what was opened: a FIFO swapped in meanwhile
    if kind is not None:
        os.close(fd)
        raise GlshadeError(f"{what} {text}: is {kind}; glshade reads only regular files")
    os.set_blocking(fd, True)
    return fd


def read_regular_text(
    path: str | os.PathLike[str], what: str, limit_bytes: int = MAX_RECORD_BYTES
) -> str:
    """:func:`read_regular` decoded as UTF-8 (one line naming the file where it is not)."""
    data = read_regular(path, what, limit_bytes)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        raise GlshadeError(f"{what} {os.fspath(path)}: is not UTF-8 text") from None


def read_regular(
    path: str | os.PathLike[str], what: str, limit_bytes: int = MAX_RECORD_BYTES
) -> bytes:
    """The bytes of the regular file ``path`` (:func:`open_regular`), at most
    ``limit_bytes``: a larger file is one line naming its size and the limit."""
    fd = open_regular(path, what)
    with os.fdopen(fd, "rb") as fh:
        data = fh.read(limit_bytes + 1)
    if len(data) > limit_bytes:
        raise GlshadeError(
            f"{what} {os.fspath(path)}: larger than {limit_bytes >> 20} MiB; not a file "
            "glshade wrote"
        )
    return data


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def quantize(image: np.ndarray, bits: int = 8) -> np.ndarray:
    """Radiance in [0, 1] (float) to unsigned integers of ``bits`` (8 or 16), rounded."""
    if bits not in (8, 16):
        raise GlshadeError(f"bits: must be 8 or 16, got {bits}")
    top = (1 << bits) - 1
    scaled = np.rint(np.clip(np.nan_to_num(image, nan=0.0), 0.0, 1.0) * top)
    return scaled.astype(np.uint8 if bits == 8 else np.uint16)


def encode_png(image: np.ndarray, bits: int = 8) -> bytes:
    """PNG bytes of a float radiance image (H×W) or an already-quantised uint8/uint16 array
    (H×W, or H×W×3 / H×W×4 in RGB(A) order)."""
    if image.dtype in (np.uint8, np.uint16):
        pixels = image
    else:
        pixels = quantize(image, bits)
    if pixels.ndim == 3 and pixels.shape[2] in (3, 4):
        pixels = np.ascontiguousarray(
            pixels[..., [2, 1, 0, 3][: pixels.shape[2]]]
        )  # OpenCV wants BGR(A)
    import cv2  # loaded by the commands that encode or decode images

    ok, buf = cv2.imencode(".png", pixels)
    if not ok:  # pragma: no cover - OpenCV only fails on unsupported dtypes
        raise GlshadeError("PNG encoding failed")
    return buf.tobytes()


def write_png(path: str | os.PathLike[str], image: np.ndarray, bits: int = 8) -> None:
    """Write a radiance image as an 8- or 16-bit greyscale PNG, atomically."""
    atomic_write_bytes(Path(path), encode_png(image, bits))


def check_image_output(path: str | os.PathLike[str], what: str, bits: int = 8) -> Path:
    """:func:`check_output` for an image: PNG (8 or 16 bits) or TIFF (8, 16 or 32 =
    float32 radiance), chosen by the extension."""
    target = check_output(path, what, tuple(IMAGE_SUFFIXES))
    if bits == 32 and IMAGE_SUFFIXES[target.suffix.lower()] != ".tiff":
        raise GlshadeError(f"{what} {path}: --bits 32 (float radiance) needs a .tif or .tiff file")
    if bits not in (8, 16, 32):
        raise GlshadeError(f"--bits: must be 8, 16 or 32, got {bits}")
    return target


def encode_image(image: np.ndarray, suffix: str, bits: int = 8) -> bytes:
    """An image file's bytes: PNG or TIFF by ``suffix``; ``bits`` 8 or 16 (rounded
    integers) or 32 (float32 radiance, TIFF only)."""
    format_ = IMAGE_SUFFIXES.get(suffix.lower())
    if format_ is None:
        raise GlshadeError(
            f"image {suffix}: {_suffix_problem(suffix.lower(), tuple(IMAGE_SUFFIXES))}"
        )
    if format_ == ".png":
        return encode_png(image, bits)
    pixels = (
        np.nan_to_num(image, nan=0.0).astype(np.float32) if bits == 32 else quantize(image, bits)
    )
    import cv2  # loaded by the commands that encode or decode images

    ok, buf = cv2.imencode(".tiff", pixels)
    if not ok:  # pragma: no cover
        raise GlshadeError("TIFF encoding failed")
    return buf.tobytes()


def read_png(path: str | os.PathLike[str]) -> np.ndarray:
    """Read a PNG written by :func:`write_png` as stored integers (uint8 or uint16)."""
    import cv2  # loaded by the commands that encode or decode images

    pixels = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if pixels is None:
        raise GlshadeError(f"{path}: not a readable PNG")
    if pixels.ndim == 3:  # OpenCV reads BGR(A): back to RGB(A), alpha stays last
        pixels = (
            pixels[..., [2, 1, 0, 3][: pixels.shape[2]]] if pixels.shape[2] in (3, 4) else pixels
        )
    return pixels


def write_npy(path: str | os.PathLike[str], array: np.ndarray, within: Path | None = None) -> None:
    """Write an array as ``.npy`` atomically (the uv map: float32 H×W×2, mm); ``within``:
    the output directory it belongs to (:func:`atomic_write_bytes`)."""
    buf = io.BytesIO()
    np.save(buf, array, allow_pickle=False)
    atomic_write_bytes(Path(path), buf.getvalue(), within=within)
