"""Which rows of a study can be judged: a row may carry a ``status`` column (``ok``,
``unresolved``, ``outside``, ``edge``, ``saturated``, ``underexposed``, ``noise``) and a
``status_reason``; rows without the column are all measurable. The verdicts, the advice
and the laws' comparison read only measurable rows; the report counts the others and the
figures mark them."""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence

#: What each status other than ``ok`` means, in the report's words.
STATUS_TEXT = {
    "unresolved": "stripes unresolved",
    "outside": "dent not seen",
    "edge": "dent at an edge (the image's, the seen region's or a height map's)",
    "saturated": "image saturated",
    "underexposed": "image underexposed",
    "noise": "shift lost in the sensor's noise",
}


def status_of(row: Mapping) -> str:
    """A row's status: ``ok`` when it has no ``status`` column (or an empty one)."""
    value = row.get("status") if hasattr(row, "get") else None
    return str(value).strip() if value not in (None, "") else "ok"


def is_measurable(row: Mapping) -> bool:
    """True when the row's numbers can be judged (its status is ``ok`` or absent)."""
    return status_of(row) == "ok"


def split_measurable(rows: Sequence[Mapping]) -> tuple[list[Mapping], list[Mapping]]:
    """``(measurable, not measurable)``, each in the rows' order."""
    ok = [r for r in rows if is_measurable(r)]
    return ok, [r for r in rows if not is_measurable(r)]


def excluded_sentence(
    rows: Sequence[Mapping], texts: Mapping[str, str] = STATUS_TEXT
) -> str | None:
    """ "3 of 18 cases not measurable: stripes unresolved (2), …", or None when every
    row is measurable (``texts``: each status in the report's words)."""
    _, bad = split_measurable(rows)
    if not bad:
        return None
    counts = Counter(status_of(r) for r in bad)
    parts = []
    for status, count in counts.most_common():
        reasons = sorted(
            {str(r.get("status_reason") or "").strip() for r in bad if status_of(r) == status}
            - {""}
        )
        why = f"; {reasons[0]}" if len(reasons) == 1 else ""
        parts.append(f"{texts.get(status, status)} ({count}{why})")
    return (
        f"{len(bad)} of {len(rows)} cases not measurable: {', '.join(parts)}. They are left "
        "out of the verdicts, the advice and the laws' comparison, and drawn as hollow grey "
        "markers in the figures."
    )
