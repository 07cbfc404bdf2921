"""Warnings about a scene that is valid but probably not what was meant.

Each active component's parameters are checked against their plausible magnitude
(``Param.plausible_max``: a dent 50 mm deep was most likely typed in µm), each component
adds its own (:meth:`Component.warnings`), and a reflection lobe too wide for the
emitter's pattern is found from the exact geometry (its footprint on the emitter,
:mod:`glshade.oracle.footprint`). Every front end prints these lines as
``glshade: warning: …``; none stops a run.
"""

from __future__ import annotations

from glshade.oracle.footprint import footprint_mm
from glshade.scene import Scene


def scene_warnings(scene: Scene) -> tuple[str, ...]:
    """The warning lines for ``scene``, each naming its field; one line per (value,
    reason), so ``defect.sigma2`` is not repeated by the two variances it sets."""
    lines: dict[tuple[object, str], str] = {}
    for component in scene.active:
        for param in component.params:
            value = scene.value(param.path)
            line = param.implausible(value)
            if line is not None:
                lines.setdefault((value, param.plausible_why), line)
        for line in (*component.warnings(scene), *_lobe_warning(scene, component)):
            lines.setdefault((None, line), line)
    return tuple(lines.values())


def _lobe_warning(scene: Scene, component) -> tuple[str, ...]:
    """A reflection lobe whose footprint on the emitter exceeds half the pattern's finest
    period along a direction it varies in washes it out (docs/physics.md, 'Glossy lobes and
    stripes')."""
    lobe = getattr(component, "lobe_std_rad", None)
    std = lobe(scene) if lobe is not None else None
    if std is None:
        return ()
    emitter = scene.active.emitter
    period = emitter.finest_period_mm(scene)
    found = [(footprint_mm(scene, std, axis), axis) for axis in emitter.pattern_axes(scene)]
    widths = [(width, axis) for width, axis in found if width is not None]
    if not widths:
        return ()
    width, axis = max(widths)
    if width <= 0.5 * period:
        return ()
    hint = component.sharpen_hint(scene, width / (0.5 * period))
    noun = emitter.pattern_noun
    along = f" along {'uv'[axis]}" if len(found) > 1 else ""
    return (
        f"render.reflection = {component.name}: the lobe spreads each point over {width:.3g} mm "
        f"of the emitter{along}, more than half the {period:g} mm {noun} period, so the "
        f"{noun}s wash out; use {hint} (docs/physics.md, 'Glossy lobes and stripes')",
    )
