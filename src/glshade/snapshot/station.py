"""What takes a snapshot: a renderer (the GL one, or the NumPy float64 oracle where no
OpenGL context can be made) that renders a scene's image and measures its numbers.

A :class:`Shot` holds the image (the emitter's peak at 1) and, per instrument, the
measured columns of its record: the paper's (:class:`glshade.instruments.record.Measurement`)
always, a phase-measuring station's (:class:`~glshade.instruments.record.PmdMeasurement`)
too where the scene's emitter shows fringes.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from glshade.errors import ContextError, GlshadeError
from glshade.scene import Scene

if TYPE_CHECKING:
    from glshade.instruments.table import MeasureTable
    from glshade.rendering import Renderer

#: How a session picks its renderer: ``auto`` the GL renderer, or the oracle where no
#: OpenGL context can be made; ``gl`` the GL renderer or an error; ``oracle`` the oracle.
CHOICES = ("auto", "gl", "oracle")
#: The largest image the oracle renders for a snapshot: 4096² (the memory budget holds too).
ORACLE_MAX_PIXELS = 4096 * 4096


@dataclass(frozen=True)
class Shot:
    """A scene rendered and measured: ``image`` (H, W) float64, the radiance that reaches
    the camera (the emitter's peak at 1; before a sensor records it, whose noise no two
    renderers draw alike); ``numbers`` per instrument the record's measured columns
    (timings and closed forms left out); ``level_step`` the largest step between the
    emitter's radiance levels (a quantised screen's; 0 for continuous stripes), by which
    a pixel may flip between renderers."""

    image: np.ndarray
    numbers: dict[str, dict[str, Any]]
    level_step: float = 0.0


class Station:
    """A renderer and what it is. ``identity``: the GL renderer string and version
    (``llvmpipe (LLVM 15.0.6, 256 bits); 4.5 (Core Profile) Mesa 22.3.6``) or the
    oracle's (``NumPy float64 oracle (glshade 0.1.0)``); ``fallback``: why the oracle
    stands in for the GL renderer (empty when it was asked for, or is not used)."""

    def __init__(self, renderer: Renderer, identity: str, fallback: str = "") -> None:
        self.renderer = renderer
        self.identity = identity
        self.fallback = fallback

    def release(self) -> None:
        self.renderer.release()

    def shoot(self, scene: Scene, table: MeasureTable | None = None) -> Shot:
        """Render ``scene``'s image and measure its numbers (``table``: its scene file's
        ``[measure]``, :func:`measured_numbers`)."""
        image = self.renderer.render(scene, ("image",), develop=False).output("image")
        step = float(scene.active.emitter.radiance_step(scene))
        numbers = measured_numbers(self.renderer, scene, table)
        return Shot(np.asarray(image, np.float64), numbers, step)


def open_station(choice: str = "auto") -> Station:
    """The renderer ``choice`` (:data:`CHOICES`) asks for."""
    if choice not in CHOICES:
        raise GlshadeError(
            f"--glshade-renderer: must be one of {', '.join(CHOICES)}, got {choice!r}"
        )
    if choice == "oracle":
        return _oracle_station("")
    from glshade.gpu.renderer import Renderer

    try:
        renderer = Renderer()  # its own context, released with it
    except ContextError as exc:
        if choice == "gl":
            raise
        return _oracle_station(str(exc))
    info = renderer.context.info()
    return Station(renderer, f"{info.renderer}; {info.version}")


def _oracle_station(fallback: str) -> Station:
    from glshade.oracle.renderer import OracleRenderer

    # at the baseline's size, however slow (about 50 µs a ray): never a smaller picture
    oracle = OracleRenderer(max_pixels=ORACLE_MAX_PIXELS)
    return Station(oracle, oracle.renderer_string, fallback)


def measured_numbers(
    renderer: Renderer, scene: Scene, table: MeasureTable | None = None
) -> dict[str, dict[str, Any]]:
    """Per instrument, the measured columns of ``scene``'s record on ``renderer``: every
    registered instrument that measures any scene (the paper's stripe metric, on the
    scene's screen), and the one the scene's emitter is measured by; each with its
    settings in ``table`` (a scene file's ``[measure]``) where the table is its own."""
    from glshade.instruments.registry import instruments

    numbers = {}
    for name, chosen in instruments().by_name.items():
        if not (chosen.always_snapshot or scene.active.emitter.measured_by == name):
            continue
        values = table.for_method(name) if table is not None else {}
        shown, settings = chosen.prepared(scene), chosen.settings(**values)
        chosen.check_case(shown, settings)
        result = chosen.measure(renderer, shown, settings)
        numbers[name] = chosen.record(shown, result).row(("measured",))
    return numbers
