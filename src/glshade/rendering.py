"""What the measuring code asks of a renderer: the :class:`Renderer` protocol.

Two classes satisfy it, and the measuring floor (``glshade.measure``, the study, the
sweeps, the snapshot station) takes either: the OpenGL renderer
(:class:`glshade.gpu.renderer.Renderer`) and the NumPy float64 oracle
(:class:`glshade.oracle.renderer.OracleRenderer`, where no OpenGL context can be made).
Neither names this protocol: they satisfy it by their shape, which mypy checks where one
is passed as a :class:`Renderer` and ``isinstance`` checks at run time (by the members'
names only).

The frames they return are :class:`glshade.frame.Frame`: radiance in [0, 1] (1: the
emitter's peak seen in a perfect mirror), or with a sensor the recorded value in [0, 1]
of full scale; emitter coordinates (``uv``) and distances in mm.

This module imports nothing at run time: the snapshot plugin and the scene stay free of
NumPy and OpenGL where they only name it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

if TYPE_CHECKING:
    from typing import Self

    from glshade.frame import Frame, Outputs
    from glshade.scene import Scene


@runtime_checkable
class Renderer(Protocol):
    """Turns scenes into frames; a context manager that releases what it holds on exit."""

    @property
    def memory_budget_bytes(self) -> int:
        """The memory budget, in bytes (default ``GLSHADE_MEMORY_BUDGET_MB``, else 2 GiB):
        a frame whose arrays would exceed it is refused in one line before any work, and
        the measuring code holds a case's buffers and analysis against it
        (:mod:`glshade.measure.memory`)."""
        ...

    def render(
        self,
        scene: Scene,
        outputs: Outputs = ("image",),
        *,
        out: Frame | None = None,
        exposure: int = 0,
        frames: Sequence[Any] | None = None,
        develop: bool = True,
    ) -> Frame:
        """One frame of ``scene``: the ``outputs`` asked for (a subset of
        :data:`glshade.frame.OUTPUTS`), each an array of ``camera.height`` x
        ``camera.width`` pixels, row 0 at the top (:class:`~glshade.frame.Frame` gives
        each one's type and unit: ``image`` radiance in [0, 1], ``uv`` emitter coordinates
        in mm, ``distance`` in mm, ...).

        ``out``: a frame whose arrays (of the types returned) are filled in place.
        ``exposure``: which of several independent exposures a sensor records (its noise;
        0, 1, ...). ``frames`` (with the ``frames`` output, and only with it): the emitter
        frames to shade from the same rays, as the emitter describes them
        (:meth:`~glshade.components.base.EmitterComponent.sequence`); the stack is
        radiance, never developed. ``develop``: with a sensor, the image is what it
        records (in [0, 1] of full scale, at ``camera.exposure``); False: the radiance
        that reaches it."""
        ...

    def exposure_gain(self, scene: Scene) -> float:
        """``scene``'s ``camera.exposure`` as a number: the factor from radiance to the
        recorded range (1 = full scale); for ``"auto"``, from the defect-free scene's
        brightest pixel (:func:`glshade.frame.auto_exposure_gain`)."""
        ...

    def release(self) -> None:
        """Let go of what the renderer holds (GL objects, kept traces and exposures)."""
        ...

    def __enter__(self) -> Self: ...

    def __exit__(self, *exc: object) -> None: ...


__all__ = ["Renderer"]
