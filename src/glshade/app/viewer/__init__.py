"""Interactive viewer (``glshade view``): turn the knobs and watch the stripes bend.

A moderngl-window window (pyglet) with an imgui-bundle control panel. The scene is traced
by the same :class:`~glshade.gpu.renderer.Renderer` and shaders as the batch renderer, into the
window's own GL context. What is recomputed is only what changed:

- a change of geometry (surface, θ, defect, emitter distance or stripes, precision,
  reflection, supersampling) re-traces the uv maps of the scene and of its defect-free
  twin;
- a change of phase (or its animation) only re-shades them on the GPU
  (``shaders/viewer_display.frag.glsl`` uses the renderer's own ``stripes.glsl``); with
  Blinn-Phong or supersampling, where the picture is not a function of the uv map, the
  image is re-rendered instead;
- the visibility metrics run in a worker thread, never on the render thread, and the
  panel shows the latest finished result; in an instrument's view (the PMD maps) the
  station measures the scene through that instrument (for phase measuring: its fringe
  sequence rendered and decoded) in a thread of its own, whenever the scene changed;
- nothing changed, nothing is drawn: the window waits for input, the worker's result or
  the animation (``FrameSchedule``), and a frame for the panel alone copies the kept
  picture instead of running the display pass again.

The package: ``controls`` (the controls, generated from the parameter schema),
``model`` (``ViewerModel`` and ``FrameSchedule``: everything but the window, tested
without a display), ``panel`` (the imgui panel, and the window height it needs),
``colourbar`` (the colour-mapped views' labelled colour bar), ``instrument_view`` (the
views the registered instruments offer, :meth:`glshade.instruments.base.Instrument.views`:
their maps and numbers, measured in a thread of its own with a renderer of its own) and
``window`` (the moderngl-window window and its event-driven loop). The scripted mode
(``--frames N --screenshot out.png --set theta=5``) runs a real window for tests and
demos. Needs the ``viewer`` extra: ``pip install "glshade[viewer]"``.
"""

from __future__ import annotations

from glshade.app.viewer.controls import (
    Choice,
    Control,
    apply_setting,
    choices,
    clamp,
    controls,
    geometry_key,
    parse_sets,
    views,
)
from glshade.app.viewer.instrument_view import STRIPE_VIEWS
from glshade.app.viewer.model import Readout, ViewerModel, ViewerOptions, readout_lines
from glshade.errors import GlshadeError
from glshade.instruments.base import InstrumentViews

#: ``glshade view``'s ``pmd_size`` when not set: an instrument view's case size where its
#: instrument does not say (:attr:`~glshade.instruments.base.InstrumentViews.size`).
PMD_SIZE = InstrumentViews.size


def run(options: ViewerOptions) -> dict:
    """Open the window and run until it is closed (or ``options.frames`` frames were
    drawn). Returns the run's statistics (frames, seconds, traces)."""
    try:
        import moderngl_window  # noqa: F401
        from imgui_bundle import imgui  # noqa: F401
    except ImportError as exc:
        raise GlshadeError(
            f"the viewer needs the viewer extra ({exc.name} is missing): "
            'pip install "glshade[viewer]"'
        ) from None
    _check_display()
    from glshade.app.viewer import window

    try:
        return window.run(options)
    except Exception as exc:  # pyglet's display errors have no common importable base
        if type(exc).__name__ in _DISPLAY_ERRORS:
            raise GlshadeError(
                f"the viewer cannot open a window ({' '.join(str(exc).split())}); "
                f"{_NO_DISPLAY_HINT}"
            ) from None
        raise


#: pyglet's exceptions for "no display" and "no usable GL configuration on it".
_DISPLAY_ERRORS = ("NoSuchDisplayException", "NoSuchConfigException", "NoSuchScreenModeException")
_NO_DISPLAY_HINT = (
    "run it on a desktop, or under a virtual display: xvfb-run -a glshade view … "
    "(Debian: apt-get install xvfb xauth)"
)


def _check_display() -> None:
    """On Linux a window needs an X11 or Wayland display: say so before pyglet fails."""
    import os
    import sys

    if sys.platform.startswith("linux") and not (
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")
    ):
        raise GlshadeError(
            f"the viewer needs a display and none is set (DISPLAY is empty); {_NO_DISPLAY_HINT}"
        )


__all__ = [
    "PMD_SIZE",
    "STRIPE_VIEWS",
    "Choice",
    "Control",
    "Readout",
    "ViewerModel",
    "ViewerOptions",
    "apply_setting",
    "choices",
    "clamp",
    "controls",
    "geometry_key",
    "parse_sets",
    "readout_lines",
    "run",
    "views",
]
