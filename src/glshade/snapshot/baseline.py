"""A snapshot's baseline on disk: ``NAME.png`` and ``NAME.json`` in the baseline folder.

- ``NAME.png``: the float image as a 16-bit greyscale PNG, ``value / scale`` (``scale`` is
  1, the emitter's peak, unless the image goes beyond it), so one step is 1.5e-5 of the
  peak;
- ``NAME.json``: the sidecar: the format, the snapshot's name, the scene (the scene
  file's tables; a height map's path relative to the baseline folder), the image's size
  and scale, the measured numbers (the paper's record; a phase-measuring station's too
  where the scene shows fringes), the renderer that made it and the glshade version.

Both are written atomically, as regular files inside the folder; the sidecar has no date,
so rewriting an unchanged baseline leaves both files byte for byte as they were.
"""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from glshade.errors import GlshadeError

#: What the sidecar's ``format`` says.
FORMAT = "glshade-snapshot"
#: Raised when the sidecar's layout changes.
FORMAT_VERSION = 1
#: A 16-bit PNG's largest value.
_TOP = 65535
#: A baseline's files are at most this large (a 4096² 16-bit PNG is about 32 MiB).
MAX_BASELINE_BYTES = 256 << 20
#: What a snapshot may be called: a file name without a folder.
NAME_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9._+-]{0,127}")


def check_name(name: object) -> str:
    """``name`` if it can name a snapshot's files, else one line saying what can."""
    if not isinstance(name, str) or NAME_PATTERN.fullmatch(name) is None:
        raise GlshadeError(
            f"snapshot name {name!r}: must be 1 to 128 letters, digits, '.', '_', '+' or '-' "
            "(a file name, no folder), starting with a letter or digit"
        )
    return name


def paths(directory: Path, name: str) -> tuple[Path, Path]:
    """``(image, sidecar)`` paths of snapshot ``name`` in ``directory``."""
    return directory / f"{name}.png", directory / f"{name}.json"


def image_scale(image: np.ndarray) -> float:
    """The PNG's full scale: 1 (the emitter's peak), or the image's largest value where it
    goes beyond the peak by more than a PNG step (a sum of nearby stripes reaches
    1.00003)."""
    largest = float(np.nanmax(image)) if image.size else 0.0
    return largest if largest > 1.0 + 1.0 / _TOP else 1.0


def encode_image(image: np.ndarray) -> bytes:
    """``image`` as a baseline stores it: a 16-bit PNG of ``image / image_scale(image)``."""
    from glshade.files import encode_png

    return encode_png(np.clip(image / image_scale(image), 0.0, 1.0), bits=16)


def finite_or_none(value: Any) -> Any:
    """A number JSON can hold: a non-finite float becomes None."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


@dataclass(frozen=True)
class Baseline:
    """A stored snapshot: ``image`` (H, W) float64 with the emitter's peak at 1,
    ``numbers`` per instrument (``paper``, ``pmd``) the record's columns, ``scene`` the
    scene file's tables, ``renderer`` what made it (:attr:`glshade.snapshot.station.
    Station.identity`), ``precision`` the scene's shader precision."""

    name: str
    image: np.ndarray
    numbers: dict[str, dict[str, Any]]
    scene: dict[str, Any]
    renderer: str
    precision: str
    glshade_version: str

    def sidecar(self, scale: float) -> dict[str, Any]:
        height, width = self.image.shape
        return {
            "format": FORMAT,
            "format_version": FORMAT_VERSION,
            "name": self.name,
            "glshade": self.glshade_version,
            "renderer": self.renderer,
            "precision": self.precision,
            "image": {"file": f"{self.name}.png", "width": width, "height": height,
                      "bits": 16, "scale": scale},
            "numbers": {
                instrument: {key: finite_or_none(value) for key, value in row.items()}
                for instrument, row in self.numbers.items()
            },
            "scene": self.scene,
        }  # fmt: skip

    def write(self, directory: Path) -> None:
        """Write (or rewrite) the baseline's two files in ``directory`` (made if missing)."""
        from glshade.files import atomic_write_bytes

        try:
            directory.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise GlshadeError(
                f"snapshot folder {directory}: cannot create it ({exc.strerror or exc})"
            ) from None
        png, side = paths(directory, self.name)
        scale = image_scale(self.image)
        pixels = encode_image(self.image)
        text = json.dumps(self.sidecar(scale), indent=2, sort_keys=False, allow_nan=False)
        atomic_write_bytes(png, pixels, "snapshot image", within=directory)
        atomic_write_bytes(side, (text + "\n").encode(), "snapshot sidecar", within=directory)


def exists(directory: Path, name: str) -> bool:
    """True when either of the baseline's files is there."""
    return any(os.path.lexists(path) for path in paths(directory, name))


def read(directory: Path, name: str) -> Baseline:
    """The baseline ``name`` of ``directory``; one line where a file is missing, is not a
    regular file, or is not what glshade writes."""
    from glshade.files import read_regular, read_regular_text

    png, side = paths(directory, name)
    text = read_regular_text(side, "snapshot sidecar", MAX_BASELINE_BYTES)
    try:
        data = json.loads(text)
    except ValueError as exc:
        raise GlshadeError(f"snapshot sidecar {side}: not JSON ({exc})") from None
    meta = _sidecar_fields(data, side)
    pixels = _decode_png(read_regular(png, "snapshot image", MAX_BASELINE_BYTES), png)
    if pixels.shape != (meta["height"], meta["width"]):
        raise GlshadeError(
            f"snapshot image {png}: is {pixels.shape[1]}x{pixels.shape[0]}, its sidecar says "
            f"{meta['width']}x{meta['height']}"
        )
    return Baseline(
        name=name,
        image=pixels.astype(np.float64) / _TOP * meta["scale"],
        numbers=data["numbers"],
        scene=data["scene"],
        renderer=data["renderer"],
        precision=data["precision"],
        glshade_version=data["glshade"],
    )


def _sidecar_fields(data: Any, side: Path) -> dict[str, Any]:
    """The image's size and scale from a sidecar, checked field by field."""
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise GlshadeError(f"snapshot sidecar {side}: not a glshade snapshot sidecar")
    if data.get("format_version") != FORMAT_VERSION:
        raise GlshadeError(
            f"snapshot sidecar {side}: format version {data.get('format_version')!r}, this "
            f"glshade reads {FORMAT_VERSION}; rewrite it with pytest --glshade-update"
        )
    image = data.get("image")
    expected = {"renderer": str, "precision": str, "glshade": str, "numbers": dict, "scene": dict}
    for key, kind in expected.items():
        if not isinstance(data.get(key), kind):
            raise GlshadeError(f"snapshot sidecar {side}: {key} missing or not a {kind.__name__}")
    if not isinstance(image, dict):
        raise GlshadeError(f"snapshot sidecar {side}: image missing or not a table")
    width, height, scale = image.get("width"), image.get("height"), image.get("scale")
    if not all(isinstance(n, int) and not isinstance(n, bool) and n > 0 for n in (width, height)):
        raise GlshadeError(f"snapshot sidecar {side}: image width/height must be whole numbers")
    if not isinstance(scale, (int, float)) or not (math.isfinite(scale) and scale > 0):
        raise GlshadeError(f"snapshot sidecar {side}: image scale must be a positive number")
    return {"width": width, "height": height, "scale": float(scale)}


def _decode_png(data: bytes, png: Path) -> np.ndarray:
    """A 16-bit greyscale PNG's values, or one line saying it is not one."""
    import cv2

    pixels = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if pixels is None or pixels.dtype != np.uint16 or pixels.ndim != 2:
        raise GlshadeError(f"snapshot image {png}: not a 16-bit greyscale PNG")
    return pixels


def stored_names(directory: Path) -> list[str]:
    """The snapshots whose sidecar lies in ``directory``, sorted (none if it is missing)."""
    try:
        entries = sorted(directory.iterdir())
    except OSError:
        return []
    return [p.stem for p in entries if p.suffix == ".json" and NAME_PATTERN.fullmatch(p.stem)]
