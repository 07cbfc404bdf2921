"""Writing results: atomic file replacement, 8/16-bit PNG, the uv map as ``.npy``.

Every writer goes through :func:`atomic_write_bytes`: the data lands in a temporary file
in the target's directory and is renamed over the target, so an interrupted run never
leaves a half-written file behind.
"""

from __future__ import annotations

import io
import os
import tempfile
from pathlib import Path

import cv2
import numpy as np

from glshade.errors import GlshadeError


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (temp file + ``os.replace``)."""
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise GlshadeError(f"{path}: is a directory, expected a file path")
    if not directory.is_dir():
        raise GlshadeError(f"{path}: directory {directory} does not exist")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    except OSError as exc:
        raise GlshadeError(f"{path}: cannot write here ({exc.strerror})") from None
    try:
        os.fchmod(fd, 0o666 & ~_umask())  # mkstemp makes 0600; a plain open() honours the umask
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
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
        pixels = np.ascontiguousarray(pixels[..., [2, 1, 0, 3][: pixels.shape[2]]])  # OpenCV wants BGR(A)
    ok, buf = cv2.imencode(".png", pixels)
    if not ok:  # pragma: no cover - OpenCV only fails on unsupported dtypes
        raise GlshadeError("PNG encoding failed")
    return buf.tobytes()


def write_png(path: str | os.PathLike[str], image: np.ndarray, bits: int = 8) -> None:
    """Write a radiance image as an 8- or 16-bit greyscale PNG, atomically."""
    atomic_write_bytes(Path(path), encode_png(image, bits))


def read_png(path: str | os.PathLike[str]) -> np.ndarray:
    """Read a PNG written by :func:`write_png` as stored integers (uint8 or uint16)."""
    pixels = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if pixels is None:
        raise GlshadeError(f"{path}: not a readable PNG")
    if pixels.ndim == 3:  # OpenCV reads BGR(A): back to RGB(A), alpha stays last
        pixels = pixels[..., [2, 1, 0, 3][: pixels.shape[2]]] if pixels.shape[2] in (3, 4) else pixels
    return pixels


def write_npy(path: str | os.PathLike[str], array: np.ndarray) -> None:
    """Write an array as ``.npy`` atomically (the uv map of SPEC §8: float32 H×W×2, mm)."""
    buf = io.BytesIO()
    np.save(buf, array, allow_pickle=False)
    atomic_write_bytes(Path(path), buf.getvalue())
