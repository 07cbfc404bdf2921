"""What a snapshot session leaves for a person to look at (``--glshade-results DIR``).

For every snapshot that moved (or has no baseline yet) the folder gets, under ``images/``,
``NAME-actual.png`` and ``NAME-expected.png`` (16-bit, as the baseline stores them) and
``NAME-diff.png``: the signed difference, magnified so the worst pixel is full scale (red
where the image is brighter now, blue where darker; a pixel beyond the tolerance is never
darker than a quarter). ``index.html`` is one page: every snapshot checked, then each
failure with its three images side by side, its numbers and its scene.
"""

from __future__ import annotations

import html
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from glshade.snapshot.compare import Comparison

#: The least brightness of a pixel beyond the tolerance in the difference image.
_BEYOND_FLOOR = 0.25


@dataclass(frozen=True)
class Entry:
    """One check of a session: ``outcome`` is ``passed``, ``moved``, ``missing`` (no
    baseline), ``written`` (``--glshade-update``) or ``broken`` (a baseline that cannot be
    read); ``images``: caption -> path relative to the results folder."""

    name: str
    test: str
    outcome: str
    detail: str
    renderer: str
    baseline_renderer: str = ""
    comparison: Comparison | None = None
    numbers: dict[str, dict[str, Any]] = field(default_factory=dict)
    expected_numbers: dict[str, dict[str, Any]] = field(default_factory=dict)
    scene_toml: str = ""
    images: dict[str, str] = field(default_factory=dict)


def magnified_difference(
    expected: np.ndarray, actual: np.ndarray, tolerance: float
) -> tuple[np.ndarray, float]:
    """The RGB difference image (uint8, H x W x 3) and its magnification."""
    delta = np.nan_to_num(actual, nan=0.0) - np.nan_to_num(expected, nan=0.0)
    largest = float(np.abs(delta).max()) if delta.size else 0.0
    gain = 1.0 / max(largest, tolerance, 1e-12)
    level = np.clip(np.abs(delta) * gain, 0.0, 1.0)
    level = np.where(np.abs(delta) > tolerance, np.maximum(level, _BEYOND_FLOOR), level)
    rgb = np.zeros((*delta.shape, 3))
    rgb[..., 0] = np.where(delta > 0, level, 0.0)
    rgb[..., 2] = np.where(delta < 0, level, 0.0)
    return np.rint(rgb * 255).astype(np.uint8), gain


def write_images(
    folder: Path, name: str, actual: np.ndarray, expected: np.ndarray | None, tolerance: float
) -> dict[str, str]:
    """The failure's images in ``folder/images``; caption -> path relative to ``folder``."""
    from glshade.files import atomic_write_bytes, encode_png, make_inside
    from glshade.snapshot.baseline import encode_image

    images = make_inside(folder, "images", "--glshade-results")
    written: dict[str, str] = {}

    def put(suffix: str, data: bytes, caption: str) -> None:
        atomic_write_bytes(images / f"{name}-{suffix}.png", data, "--glshade-results", folder)
        written[caption] = f"images/{name}-{suffix}.png"

    put("actual", encode_image(actual), "actual")
    if expected is not None:
        put("expected", encode_image(expected), "expected")
    if expected is not None and expected.shape == actual.shape:
        rgb, gain = magnified_difference(expected, actual, tolerance)
        put("diff", encode_png(rgb), f"difference ×{gain:.3g} (red: brighter now, blue: darker)")
    return written


def number_rows(entry: Entry) -> list[dict[str, str]]:
    """The numbers table of a failure: every number either side has, compared ones first."""
    compared = {
        (c.instrument, c.name): c for c in (entry.comparison.numbers if entry.comparison else ())
    }
    rows = []
    instruments = sorted(set(entry.numbers) | set(entry.expected_numbers))
    for instrument in instruments:
        now, then = entry.numbers.get(instrument, {}), entry.expected_numbers.get(instrument, {})
        for key in dict.fromkeys([*then, *now]):
            change = compared.get((instrument, key))
            tolerance = (
                ""
                if change is None
                else "same"
                if change.tolerance is None
                else f"{change.tolerance:g} {change.unit}"
            )
            rows.append({
                "instrument": instrument, "name": key,
                "expected": _text(then.get(key, "—")), "actual": _text(now.get(key, "—")),
                "tolerance": tolerance or "recorded",
                "state": "moved" if change is not None and change.moved else "",
                "kind": "num" if _numeric(then.get(key)) or _numeric(now.get(key)) else "text",
            })  # fmt: skip
    rows.sort(key=lambda r: (r["state"] != "moved", r["tolerance"] == "recorded"))
    return rows


def _numeric(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _text(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    return "none" if value is None else str(value)


def scene_text(tables: dict[str, Any]) -> str:
    """The scene as a scene file holds it (TOML), one line a key."""
    lines = []
    for table, values in tables.items():
        lines.append(f"[{table}]")
        for key, value in values.items():
            if isinstance(value, (list, tuple)):
                shown = "[" + ", ".join(_toml_scalar(item) for item in value) + "]"
            else:
                shown = _toml_scalar(value)
            lines.append(f"{key} = {shown}")
        lines.append("")
    return "\n".join(lines)


def _toml_scalar(value: Any) -> str:
    import tomli_w

    return tomli_w.dumps({"x": value}).split("=", 1)[1].strip()


def summary_html(entries: list[Entry], header: dict[str, str]) -> str:
    """The one-page summary of a session's checks."""
    import jinja2

    env = jinja2.Environment(
        loader=jinja2.PackageLoader("glshade.snapshot", "."),
        autoescape=jinja2.select_autoescape(["html", "j2"]),
    )
    order = {"moved": 0, "missing": 1, "broken": 2, "written": 3, "passed": 4}
    shown = sorted(entries, key=lambda e: (order.get(e.outcome, 5), e.name))
    counts = {outcome: sum(e.outcome == outcome for e in entries) for outcome in order}
    failures = [(e, number_rows(e)) for e in shown if e.outcome in ("moved", "missing", "broken")]
    return env.get_template("summary.html.j2").render(
        entries=shown, failures=failures, counts=counts, header=header, escape=html.escape
    )


def write_summary(folder: Path, entries: list[Entry], header: dict[str, str]) -> Path:
    """``folder/index.html``."""
    from glshade.files import atomic_write_bytes

    page = folder / "index.html"
    atomic_write_bytes(page, summary_html(entries, header).encode(), "--glshade-results", folder)
    return page
