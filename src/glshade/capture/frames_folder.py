"""A glshade ``--frames`` folder (:func:`glshade.instruments.pmd.files.write_frames`) as a
:class:`~glshade.capture.model.Capture`, and back: ``manifest.json`` and one image per
frame (16-bit PNG: value / 65535; or 32-bit float TIFF: the value)."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from glshade.capture.model import Capture, CaptureCoding
from glshade.components.emitter.fringes.codec import FringeCodec
from glshade.errors import GlshadeError
from glshade.files import atomic_write_bytes, encode_image
from glshade.instruments.pmd.files import FRAME_ENCODING, FRAME_FORMATS, frame_entry, frame_name

MANIFEST = "manifest.json"


def read_image(path: Path, what: str) -> np.ndarray:
    """One greyscale image as float64 recorded values: 8/16-bit integers over their full
    scale, float images as stored; one line naming the file otherwise."""
    import cv2

    if not path.is_file():
        raise GlshadeError(f"{what}: {path}: no such file")
    pixels = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if pixels is None:
        raise GlshadeError(f"{what}: {path}: not a readable PNG or TIFF image")
    return as_values(pixels, path, what)


def as_values(pixels: np.ndarray, path: Path | str, what: str) -> np.ndarray:
    """Stored pixels as float64 recorded values (one channel expected)."""
    if pixels.ndim != 2:
        raise GlshadeError(f"{what}: {path}: a greyscale image expected, got shape {pixels.shape}")
    if pixels.dtype == np.uint8:
        return pixels.astype(np.float64) / 255.0
    if pixels.dtype == np.uint16:
        return pixels.astype(np.float64) / 65535.0
    if pixels.dtype in (np.float32, np.float64):
        return pixels.astype(np.float64)
    raise GlshadeError(f"{what}: {path}: 8- or 16-bit or float pixels expected, got {pixels.dtype}")


def _format_of(manifest: dict[str, Any], where: str) -> str:
    for name, text in FRAME_ENCODING.items():
        if manifest.get("format") == text:
            return name
    raise GlshadeError(f"{where}: format must be one of {list(FRAME_ENCODING.values())}")


def read_frames_folder(path: str | os.PathLike[str]) -> Capture:
    """The capture a ``--frames`` folder holds (one line naming the file on bad input)."""
    folder = Path(path)
    where = str(folder / MANIFEST)
    if not folder.is_dir():
        raise GlshadeError(f"{folder}: not a directory (a --frames folder expected)")
    if not (folder / MANIFEST).is_file():
        raise GlshadeError(f"{where}: no such file (a --frames folder holds one)")
    try:
        manifest = json.loads((folder / MANIFEST).read_text())
        fmt = _format_of(manifest, where)
        codec = FringeCodec.from_dict(manifest["coding"])
        entries = sorted(manifest["frames"], key=lambda e: int(e["index"]))
        white_name = manifest.get("white", {}).get("file")
        response = manifest.get("white", {}).get("response")
    except (ValueError, KeyError, TypeError, AttributeError) as error:
        raise GlshadeError(f"{where}: not a frames manifest ({error})") from None
    except GlshadeError as error:
        raise GlshadeError(f"{where}: {error}") from None
    coding = CaptureCoding.of_codec(codec)
    if len(entries) != coding.frame_count:
        raise GlshadeError(
            f"{where}: {coding.frame_count} frames for its coding, the manifest lists "
            f"{len(entries)}"
        )
    frames = _read_stack(folder, [str(e["file"]) for e in entries], "--frames")
    white = None
    if white_name:
        white = read_image(folder / white_name, "--frames")
        _check_size(white, frames.shape[1:], folder / white_name)
    scene = None
    if "scene" in manifest:
        from glshade.scene import Scene

        try:
            scene = Scene.from_dict(manifest["scene"])
        except GlshadeError:
            scene = None
    return Capture(
        frames,
        coding,
        white=white,
        peak_response=None if response is None else float(response),
        scene=scene,
        source=str(folder),
        extra={"manifest": manifest, "format": fmt},
    )


def _check_size(image: np.ndarray, shape: tuple[int, ...], path: Path) -> None:
    if image.shape != tuple(shape):
        raise GlshadeError(
            f"{path}: {shape[0]} x {shape[1]} pixels expected (as the first frame), got "
            f"{image.shape[0]} x {image.shape[1]}"
        )


def _read_stack(folder: Path, names: list[str], what: str) -> np.ndarray:
    first = read_image(folder / names[0], what)
    frames = np.empty((len(names), *first.shape))
    frames[0] = first
    for index, name in enumerate(names[1:], 1):
        image = read_image(folder / name, what)
        _check_size(image, first.shape, folder / name)
        frames[index] = image
    return frames


def write_frames_folder(
    path: str | os.PathLike[str], capture: Capture, fmt: str | None = None
) -> Path:
    """Write ``capture`` as a ``--frames`` folder (the manifest it was read with, when it
    came from one; else one of its coding in glshade's order); returns the manifest's path.
    ``fmt``: ``png`` or ``tif`` (default: the one it was read from, else png)."""
    folder = Path(path)
    folder.mkdir(parents=False, exist_ok=True)
    fmt = fmt or capture.extra.get("format", "png")
    suffix, bits = FRAME_FORMATS[fmt]
    manifest = dict(capture.extra.get("manifest") or {})
    codec = capture.coding.codec()
    blocks = capture.coding.glshade_order(capture.frames)
    entries, names = [], []
    index = 0
    for frame in codec.frames():
        image = blocks[frame.direction][frame.period_index, frame.shift_index]
        name = frame_name(index, frame, suffix)
        atomic_write_bytes(
            folder / name, encode_image(image, suffix, bits), "--frames", within=folder
        )
        names.append(name)
        entries.append(frame_entry(index, frame, name))
        index += 1
    white_entry = dict(manifest.get("white") or {})
    if capture.white is not None:
        white = "frame_white" + suffix
        atomic_write_bytes(
            folder / white, encode_image(capture.white, suffix, bits), "--frames", within=folder
        )
        white_entry["file"] = white
        white_entry.setdefault("response", capture.peak_response)
    elif capture.peak_response is not None:
        white_entry = {"file": None, "response": capture.peak_response}
    if fmt != capture.extra.get("format") or "coding" not in manifest:
        manifest["format"] = FRAME_ENCODING[fmt]
        manifest["coding"] = codec.to_dict()
    manifest.setdefault("format", FRAME_ENCODING[fmt])
    manifest["white"] = white_entry
    manifest["frames"] = entries
    text = json.dumps(manifest, indent=2, default=str) + "\n"
    target = folder / MANIFEST
    atomic_write_bytes(target, text.encode(), "--frames", within=folder)
    return target
