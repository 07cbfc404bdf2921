"""Writing results: atomic file replacement, PNG and TIFF images, the uv map as ``.npy``.

Every writer goes through :func:`atomic_write_bytes`: the data lands in a temporary file
in the target's directory and is renamed over the target, so an interrupted run never
leaves a half-written file behind. Outputs are only ever regular files: a path that is a
directory, a device, a FIFO or a socket is refused (:func:`check_output`), and the
front ends check every output path before any work starts.
"""

from __future__ import annotations

import io
import os
import stat
import tempfile
from pathlib import Path

import cv2
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


def check_output(
    path: str | os.PathLike[str], what: str = "output", suffixes: tuple[str, ...] = ()
) -> Path:
    """The regular file ``path`` will be written as (a symbolic link is written through),
    or a :class:`GlshadeError` naming ``what`` (a flag such as ``-o``) and why not: an
    existing directory, device, FIFO or socket, a missing or unwritable directory, or an
    extension not in ``suffixes`` (lower case, with the dot; empty: any)."""
    text = os.fspath(path)
    if not text or text.endswith(os.sep) or "\0" in text:
        raise GlshadeError(f"{what} {text!r}: expected a file path")
    path = Path(os.path.realpath(text))
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        mode = None
    except OSError as exc:
        raise GlshadeError(f"{what} {text}: cannot use it ({exc.strerror})") from None
    if mode is not None and not stat.S_ISREG(mode):
        kind = next((name for test, name in _KINDS if test(mode)), "not a regular file")
        raise GlshadeError(f"{what} {text}: is {kind}; glshade only writes regular files")
    if suffixes and path.suffix.lower() not in suffixes:
        raise GlshadeError(f"{what} {text}: {_suffix_problem(path.suffix.lower(), suffixes)}")
    shown = os.path.dirname(text) or "."
    if not path.parent.is_dir():
        raise GlshadeError(f"{what} {text}: directory {shown} does not exist")
    if not os.access(path.parent, os.W_OK | os.X_OK):
        raise GlshadeError(f"{what} {text}: directory {shown} is not writable")
    return path


def _suffix_problem(suffix: str, suffixes: tuple[str, ...]) -> str:
    allowed = ", ".join(suffixes)
    if suffix in _LOSSY:
        return (
            f"{suffix} is a lossy format, which would blur the stripe edges; use one of {allowed}"
        )
    return f"the extension {suffix or '(none)'} is not supported; use one of {allowed}"


def atomic_write_bytes(path: Path, data: bytes, what: str = "output") -> None:
    """Write ``data`` to ``path`` atomically (temp file + ``os.replace``); only ever a
    regular file (see :func:`check_output`)."""
    target = check_output(path, what)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    except OSError as exc:
        raise GlshadeError(f"{what} {path}: cannot write here ({exc.strerror})") from None
    try:
        os.fchmod(fd, 0o666 & ~_umask())  # mkstemp makes 0600; a plain open() honours the umask
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
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
    ok, buf = cv2.imencode(".tiff", pixels)
    if not ok:  # pragma: no cover
        raise GlshadeError("TIFF encoding failed")
    return buf.tobytes()


def write_image(
    path: str | os.PathLike[str], image: np.ndarray, bits: int = 8, what: str = "-o"
) -> None:
    """Write a radiance image in the format its extension names (PNG or TIFF), atomically."""
    target = check_image_output(path, what, bits)
    atomic_write_bytes(Path(path), encode_image(image, target.suffix, bits), what)


def read_png(path: str | os.PathLike[str]) -> np.ndarray:
    """Read a PNG written by :func:`write_png` as stored integers (uint8 or uint16)."""
    pixels = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if pixels is None:
        raise GlshadeError(f"{path}: not a readable PNG")
    if pixels.ndim == 3:  # OpenCV reads BGR(A): back to RGB(A), alpha stays last
        pixels = (
            pixels[..., [2, 1, 0, 3][: pixels.shape[2]]] if pixels.shape[2] in (3, 4) else pixels
        )
    return pixels


def write_npy(path: str | os.PathLike[str], array: np.ndarray) -> None:
    """Write an array as ``.npy`` atomically (the uv map: float32 H×W×2, mm)."""
    buf = io.BytesIO()
    np.save(buf, array, allow_pickle=False)
    atomic_write_bytes(Path(path), buf.getvalue())
