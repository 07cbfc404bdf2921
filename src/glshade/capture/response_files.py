"""Display responses read from what a user types (docs/captures.md): ``gamma:G``, a
measured curve in a CSV or TOML file, or an OpenCSP image calibration record."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from glshade.capture.response import Response
from glshade.errors import GlshadeError


def parse_response(text: str) -> Response:
    """``gamma:G``, or a file: ``.csv`` (two columns: recorded, commanded; a header line
    allowed), ``.toml`` (``recorded = [...]``, ``commanded = [...]``) or an OpenCSP
    ``image_calibration.h5``."""
    if text.startswith("gamma:"):
        try:
            gamma = float(text[len("gamma:") :])
        except ValueError:
            gamma = math.nan
        if not (math.isfinite(gamma) and gamma > 0):
            raise GlshadeError(f"--response {text}: gamma:G with G a finite number above 0")
        return Response("gamma", gamma=gamma, source=text)
    path = Path(text)
    if not path.is_file():
        raise GlshadeError(
            f"--response {text}: no such file (gamma:G, or a .csv, .toml or OpenCSP .h5 curve)"
        )
    suffix = path.suffix.lower()
    if suffix in (".h5", ".hdf5"):
        from glshade.capture.sofast import read_sofast_calibration

        try:
            return read_sofast_calibration(path).as_response(str(path))
        except GlshadeError as error:
            raise GlshadeError(
                f"--response {error} (allowed: gamma:G, a .csv or .toml curve, an OpenCSP "
                "image_calibration.h5)"
            ) from None
    if suffix == ".csv":
        return _csv_response(path)
    if suffix == ".toml":
        return _toml_response(path)
    raise GlshadeError(f"--response {text}: a .csv, .toml or .h5 file, or gamma:G")


def _csv_response(path: Path) -> Response:
    rows = []
    for number, line in enumerate(path.read_text().splitlines(), 1):
        cells = [c.strip() for c in line.replace(";", ",").split(",") if c.strip()]
        if not cells:
            continue
        try:
            rows.append((float(cells[0]), float(cells[1])))
        except (ValueError, IndexError):
            if number == 1:
                continue  # a header
            raise GlshadeError(
                f"{path}:{number}: two numbers (recorded, commanded), got {line!r}"
            ) from None
    pairs = np.array(rows, float).reshape(-1, 2)
    return Response("measured", recorded=pairs[:, 0], commanded=pairs[:, 1], source=str(path))


def _toml_response(path: Path) -> Response:
    from glshade.scene.model import read_toml

    data = read_toml(path, "response curve")
    try:
        recorded = np.asarray(data["recorded"], float)
        commanded = np.asarray(data["commanded"], float)
    except (KeyError, ValueError, TypeError):
        raise GlshadeError(
            f"{path}: needs recorded = [numbers] and commanded = [numbers]"
        ) from None
    return Response("measured", recorded=recorded, commanded=commanded, source=str(path))
