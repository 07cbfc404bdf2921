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

A baseline is read as a file someone else may have written: the sidecar at most
:data:`MAX_SIDECAR_BYTES`, its tables nested at most :data:`MAX_SIDECAR_DEPTH` deep
(counted before it is parsed), every field of its type (the numbers each a column of its
instrument's record, within that column's range: :mod:`glshade.instruments.record`; every
text one line); the PNG's header read before a sample is decoded, its size the
sidecar's and at most :data:`MAX_BASELINE_PIXELS`. Anything else is one line naming the
file.
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
#: A baseline's image file is at most this large (a 4096² 16-bit PNG is about 32 MiB).
MAX_BASELINE_BYTES = 256 << 20
#: The most pixels a baseline holds: the largest image a snapshot can be compared on every
#: renderer (the oracle, which stands in where OpenGL cannot run, renders no more). A
#: 16384² 16-bit PNG of 0.5 MB would decode to 512 MiB, and 2.7 GB as the float image;
#: its header is refused before that.
MAX_BASELINE_PIXELS = 4096 * 4096
#: A sidecar is at most this large (a scene's tables and two records: a few KiB).
MAX_SIDECAR_BYTES = 1 << 20
#: How deep a sidecar's tables and lists may nest (glshade writes four levels).
MAX_SIDECAR_DEPTH = 16
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

        height, width = self.image.shape
        if width * height > MAX_BASELINE_PIXELS:
            raise GlshadeError(
                f"snapshot {self.name!r}: the image is {width}x{height} pixels, more than a "
                f"baseline holds ({MAX_BASELINE_PIXELS} pixels, 4096x4096: the most the "
                "oracle renders); snapshot the scene at a smaller size (scene.with_size)"
            )
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
    data = parse_sidecar(read_regular_text(side, "snapshot sidecar", MAX_SIDECAR_BYTES), side)
    meta = _sidecar_fields(data, side)
    raw = read_regular(png, "snapshot image", MAX_BASELINE_BYTES)
    _check_header(raw, png, meta)
    pixels = _decode_png(raw, png)
    if pixels.shape != (meta["height"], meta["width"]):
        raise GlshadeError(f"snapshot image {png}: not a 16-bit greyscale PNG")
    return Baseline(
        name=name,
        image=pixels.astype(np.float64) / _TOP * meta["scale"],
        numbers=data["numbers"],
        scene=data["scene"],
        renderer=data["renderer"],
        precision=data["precision"],
        glshade_version=data["glshade"],
    )


_STRING = re.compile(r'"(?:[^"\\]|\\.)*"')
_BRACKET = re.compile(r"[\[\]{}]")


def nesting(text: str, limit: int = MAX_SIDECAR_DEPTH) -> int:
    """How deep the JSON ``text``'s arrays and objects nest (counted without parsing it,
    strings left out), at most ``limit + 1``: a reader stops there."""
    depth = deepest = 0
    for bracket in _BRACKET.finditer(_STRING.sub('""', text)):
        depth += 1 if bracket.group() in "[{" else -1
        deepest = max(deepest, depth)
        if deepest > limit:
            break
    return deepest


def parse_sidecar(text: str, side: Path) -> Any:
    """A sidecar's JSON, its nesting bounded before it is parsed (a file 100 000 levels
    deep would exhaust the parser's recursion)."""
    if nesting(text) > MAX_SIDECAR_DEPTH:
        raise GlshadeError(
            f"snapshot sidecar {side}: nested more than {MAX_SIDECAR_DEPTH} levels deep; not "
            "a sidecar glshade writes"
        )
    try:
        return json.loads(text)
    except (ValueError, RecursionError) as exc:
        raise GlshadeError(f"snapshot sidecar {side}: not JSON ({exc})") from None


def _sidecar_fields(data: Any, side: Path) -> dict[str, Any]:
    """The image's size and scale from a sidecar, checked field by field (and the rest of
    it: :func:`_check_numbers`, :func:`_check_scene`, :func:`_check_texts`)."""
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise GlshadeError(f"snapshot sidecar {side}: not a glshade snapshot sidecar")
    if data.get("format_version") != FORMAT_VERSION:
        raise GlshadeError(
            f"snapshot sidecar {side}: format version {data.get('format_version')!r}, this "
            f"glshade reads {FORMAT_VERSION}; rewrite it with pytest --glshade-update"
        )
    expected = {"renderer": str, "precision": str, "glshade": str, "numbers": dict, "scene": dict}
    for key, kind in expected.items():
        if not isinstance(data.get(key), kind):
            raise GlshadeError(f"snapshot sidecar {side}: {key} missing or not a {kind.__name__}")
    meta = _image_fields(data.get("image"), side)
    _check_texts(data, side, "")
    _check_numbers(data["numbers"], side)
    _check_scene(data["scene"], side)
    return meta


def _image_fields(image: Any, side: Path) -> dict[str, Any]:
    """The sidecar's ``image``: whole sides of at most :data:`MAX_BASELINE_PIXELS`
    pixels in all, a positive finite scale."""
    if not isinstance(image, dict):
        raise GlshadeError(f"snapshot sidecar {side}: image missing or not a table")
    width, height, scale = image.get("width"), image.get("height"), image.get("scale")
    if not (_whole(width) and _whole(height)):
        raise GlshadeError(f"snapshot sidecar {side}: image width/height must be whole numbers")
    assert isinstance(width, int) and isinstance(height, int)
    if width * height > MAX_BASELINE_PIXELS:
        raise GlshadeError(
            f"snapshot sidecar {side}: image of {width}x{height} pixels, more than a baseline "
            f"holds ({MAX_BASELINE_PIXELS}: 4096x4096)"
        )
    if isinstance(scale, bool) or not isinstance(scale, (int, float)):
        raise GlshadeError(f"snapshot sidecar {side}: image scale must be a positive number")
    if not (0 < scale <= 1e12):  # an int of any size compares exactly
        raise GlshadeError(f"snapshot sidecar {side}: image scale must be a positive number")
    return {"width": width, "height": height, "scale": float(scale)}


def _whole(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value > 0


def _check_texts(value: Any, side: Path, where: str) -> None:
    """Every text of the sidecar (keys too) one line glshade could have written: at most
    4096 characters, no control character (a stored text reaches a test's message)."""
    from glshade.instruments.record import text_problem

    texts = (
        value.items()
        if isinstance(value, dict)
        else enumerate(value)
        if isinstance(value, list)
        else ()
    )
    for key, item in texts:
        name = f"{where}.{key}" if where else str(key)
        problem = text_problem(name, key) if isinstance(key, str) else None
        if isinstance(item, str):
            problem = problem or text_problem(name, item)
        if problem is not None:
            raise GlshadeError(f"snapshot sidecar {side}: {problem}")
        _check_texts(item, side, name)


def _check_numbers(numbers: dict, side: Path) -> None:
    """``numbers``: per registered instrument a table of its record's columns, each of
    the column's type and within its range; another key of a table any one value (shown
    beside the compared numbers, never compared)."""
    from glshade.instruments.registry import instruments

    records = {name: item.record_type for name, item in instruments().by_name.items()}
    for instrument, table in numbers.items():
        if instrument not in records or not isinstance(table, dict):
            raise GlshadeError(
                f"snapshot sidecar {side}: numbers.{instrument} must be the table of an "
                f"instrument's numbers ({', '.join(records)})"
            )
        for key, value in table.items():
            if isinstance(value, (dict, list)):
                problem: str | None = f"holds a {type(value).__name__} as {key}, not a number"
            else:
                problem = records[instrument].field_problem(key, value)
            if problem is not None:
                raise GlshadeError(f"snapshot sidecar {side}: numbers.{instrument} {problem}")


def _check_scene(scene: dict, side: Path) -> None:
    """``scene``: the scene file's tables, each a table of keys."""
    for table, values in scene.items():
        if not isinstance(values, dict):
            raise GlshadeError(f"snapshot sidecar {side}: scene.{table} must be a table of keys")


def _check_header(raw: bytes, png: Path, meta: dict[str, Any]) -> None:
    """The PNG's header (its first 33 bytes), before a sample is decoded: 16-bit grey, at
    most :data:`MAX_BASELINE_PIXELS` pixels, the size its sidecar says."""
    from glshade.image_header import ImageHeaderError, check_pixels, png_header

    name = f"snapshot image {png}"
    try:
        header = png_header(raw[:33], name)
    except ImageHeaderError as exc:
        why = str(exc).removeprefix(f"{name}: ")
        raise GlshadeError(f"{name}: not a 16-bit greyscale PNG ({why})") from None
    check_pixels(header, MAX_BASELINE_PIXELS, name, "a baseline holds at most 4096x4096")
    if (header.bit_depth, header.channels) != (16, 1):
        raise GlshadeError(f"{name}: not a 16-bit greyscale PNG ({header.describe()})")
    if (header.width, header.height) != (meta["width"], meta["height"]):
        raise GlshadeError(
            f"{name}: is {header.width}x{header.height}, its sidecar says "
            f"{meta['width']}x{meta['height']}"
        )


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
