"""Warnings about a scene that is valid but probably not what was meant.

Each active component's parameters are checked against their plausible magnitude
(``Param.plausible_max``: a dent 50 mm deep was most likely typed in µm), and each
component adds its own (a reflection lobe too wide for the stripes). Every front end
prints these lines as ``glshade: warning: …``; none stops a run.
"""

from __future__ import annotations

from glshade.components.registry import registry


def scene_warnings(scene) -> tuple[str, ...]:
    """The warning lines for ``scene``, each naming its field; one line per (value,
    reason), so ``defect.sigma2`` is not repeated by the two variances it sets."""
    lines: dict[tuple[object, str], str] = {}
    for component in registry().active(scene):
        for param in component.params:
            value = scene.value(param.path)
            line = param.implausible(value)
            if line is not None:
                lines.setdefault((value, param.plausible_why), line)
        for line in component.warnings(scene):
            lines.setdefault((None, line), line)
    return tuple(lines.values())
