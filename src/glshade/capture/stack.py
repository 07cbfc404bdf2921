"""An image stack and a coding file as a :class:`~glshade.capture.model.Capture`, and back
(docs/captures.md): a folder of 8- or 16-bit PNG or TIFF images (one per frame, in the
order of their names) or one multi-page TIFF, and a TOML file of the coding
(:meth:`~glshade.capture.model.CaptureCoding.from_dict`'s keys) with an optional
``[references]`` table: ``black``, ``white`` (image files beside the stack) and
``peak_response``."""

from __future__ import annotations

import os
import tomllib
from pathlib import Path
from typing import Any

import numpy as np

from glshade.capture.frames_folder import _check_size, as_values, read_image
from glshade.capture.model import Capture, CaptureCoding
from glshade.errors import GlshadeError
from glshade.files import atomic_write_bytes, encode_image

#: The image files a stack folder's frames may be.
SUFFIXES = (".png", ".tif", ".tiff")


def read_coding_file(path: str | os.PathLike[str]) -> tuple[CaptureCoding, dict[str, Any]]:
    """The coding and the references table of a coding file (one line on bad input)."""
    target = Path(path)
    if not target.is_file():
        raise GlshadeError(f"--coding {target}: no such file")
    try:
        values = tomllib.loads(target.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as error:
        raise GlshadeError(f"--coding {target}: not TOML ({error})") from None
    references = values.pop("references", {})
    if not isinstance(references, dict):
        raise GlshadeError(f"--coding {target}: references must be a table")
    unknown = sorted(set(references) - {"black", "white", "peak_response"})
    if unknown:
        raise GlshadeError(f"--coding {target}: references: unknown key {unknown[0]}")
    return CaptureCoding.from_dict(values, f"--coding {target}"), references


def read_stack(path: str | os.PathLike[str], coding_file: str | os.PathLike[str]) -> Capture:
    """The capture of an image stack (a folder, or a multi-page TIFF) and its coding file."""
    source = Path(path)
    coding, references = read_coding_file(coding_file)
    base = source if source.is_dir() else source.parent
    named = {str(references[k]) for k in ("black", "white") if k in references}
    if source.is_dir():
        names = sorted(
            p.name
            for p in source.iterdir()
            if p.suffix.lower() in SUFFIXES and p.name not in named and p.is_file()
        )
        if len(names) != coding.frame_count:
            raise GlshadeError(
                f"{source}: {coding.frame_count} frame images for the coding of {coding_file}, "
                f"found {len(names)}"
            )
        first = read_image(source / names[0], "stack")
        frames = np.empty((len(names), *first.shape))
        frames[0] = first
        for index, name in enumerate(names[1:], 1):
            image = read_image(source / name, "stack")
            _check_size(image, first.shape, source / name)
            frames[index] = image
    elif source.is_file():
        frames = _read_multipage(source)
        if frames.shape[0] != coding.frame_count:
            raise GlshadeError(
                f"{source}: {coding.frame_count} pages for the coding of {coding_file}, "
                f"found {frames.shape[0]}"
            )
    else:
        raise GlshadeError(f"{source}: no such file or directory (an image stack expected)")
    images: dict[str, np.ndarray] = {}
    for key in ("black", "white"):
        if key in references:
            image = read_image(base / str(references[key]), f"--coding {coding_file}: {key}")
            _check_size(image, frames.shape[1:], base / str(references[key]))
            images[key] = image
    peak = references.get("peak_response")
    if peak is not None and not isinstance(peak, int | float):
        raise GlshadeError(f"--coding {coding_file}: references.peak_response must be a number")
    return Capture(
        frames,
        coding,
        black=images.get("black"),
        white=images.get("white"),
        peak_response=None if peak is None else float(peak),
        source=str(source),
        extra={"references": references},
    )


def _read_multipage(path: Path) -> np.ndarray:
    import tifffile

    try:
        pages = tifffile.imread(path)
    except Exception as error:  # tifffile raises many kinds on a bad file
        raise GlshadeError(f"{path}: not a readable TIFF ({type(error).__name__})") from None
    pages = np.asarray(pages)
    if pages.ndim == 2:
        pages = pages[None]
    if pages.ndim != 3:
        raise GlshadeError(f"{path}: greyscale pages expected, got shape {pages.shape}")
    return np.stack([as_values(page, path, "stack") for page in pages])


def coding_text(coding: CaptureCoding, references: dict[str, Any] | None = None) -> str:
    """A coding file's TOML text."""
    lines = [f"{key} = {_toml(value)}" for key, value in coding.to_dict().items()]
    if references:
        lines += ["", "[references]"]
        lines += [f"{key} = {_toml(value)}" for key, value in references.items()]
    return "\n".join(lines) + "\n"


def _toml(value: Any) -> str:
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, list | tuple):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value)


def _stored(frames: np.ndarray) -> np.ndarray:
    """The frames as a TIFF stores them without loss: 16-bit integers where they are
    whole multiples of 1/65535 in [0, 1], else float32 where that holds them, else float64."""
    scaled = np.rint(frames * 65535.0)
    if np.all((scaled >= 0) & (scaled <= 65535)) and np.array_equal(scaled / 65535.0, frames):
        return scaled.astype(np.uint16)
    single = frames.astype(np.float32)
    return (
        single if np.array_equal(single.astype(np.float64), frames) else frames.astype(np.float64)
    )


def _image_bytes(image: np.ndarray, suffix: str, bits: int) -> bytes:
    if suffix == ".png":
        return encode_image(image, suffix, bits)
    import io

    import tifffile

    buf = io.BytesIO()
    tifffile.imwrite(buf, _stored(np.asarray(image)))
    return buf.getvalue()


def write_stack(
    path: str | os.PathLike[str],
    capture: Capture,
    coding_file: str | os.PathLike[str],
    fmt: str = "png",
) -> None:
    """Write ``capture`` as a stack: ``fmt`` ``png`` (a folder of 16-bit PNG frames,
    ``frame_000.png`` …) or ``tiff`` (one multi-page TIFF at ``path``: 16-bit, float32
    or float64, whichever holds the values without loss), its references beside it, and
    its coding file."""
    target = Path(path)
    references: dict[str, Any] = {}
    if fmt == "png":
        target.mkdir(parents=False, exist_ok=True)
        base = target
        for index, frame in enumerate(capture.frames):
            name = target / f"frame_{index:03d}.png"
            atomic_write_bytes(name, encode_image(frame, ".png", 16), "stack", within=target)
        suffix, bits = ".png", 16
    elif fmt == "tiff":
        import io

        import tifffile

        buf = io.BytesIO()
        tifffile.imwrite(buf, _stored(np.asarray(capture.frames)))
        atomic_write_bytes(target, buf.getvalue(), "stack")
        base = target.parent
        suffix, bits = ".tif", 32
    else:
        raise GlshadeError(f"stack format: png or tiff, got {fmt!r}")
    for key in ("black", "white"):
        image = getattr(capture, key)
        if image is not None:
            file = f"{target.name}_{key}{suffix}" if fmt == "tiff" else f"{key}{suffix}"
            atomic_write_bytes(base / file, _image_bytes(image, suffix, bits), "stack")
            references[key] = file
    if capture.peak_response is not None:
        references["peak_response"] = capture.peak_response
    atomic_write_bytes(
        Path(coding_file), coding_text(capture.coding, references).encode(), "--coding"
    )
