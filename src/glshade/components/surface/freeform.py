"""What the free-form surfaces (a formula, a height map) share: the uniforms of the
library's free-form march (``lib/freeform.glsl``)."""

from __future__ import annotations

from typing import Protocol

#: Steps of the first-hit march (it converges from above in a few; skimming rays take more).
MARCH_STEPS = 256
#: The GLSL every free-form surface puts before its own.
MARCH_GLSL = ("lib/march.glsl", "lib/freeform.glsl")


#: Most iterations of the free-form polish (``lib/freeform.glsl``).
POLISH_ITERATIONS = 64


class MarchSolver(Protocol):
    """What the march reads of the renderer's dent solver
    (:class:`glshade.gpu.renderer.RootSolver`)."""

    @property
    def march_steps(self) -> int: ...

    def tolerance_for(self, precision: str) -> float: ...


class _Defect(Protocol):
    @property
    def present(self) -> bool: ...


class _Render(Protocol):
    @property
    def precision(self) -> str: ...


class MarchScene(Protocol):
    """What the march reads of a scene: whether it has a dent, and the shader's
    precision."""

    @property
    def defect(self) -> _Defect: ...

    @property
    def render(self) -> _Render: ...


class MarchContext(Protocol):
    """What the march's uniforms read of the uniform context: the renderer's solver."""

    @property
    def solver(self) -> MarchSolver: ...


def march_steps(solver: MarchSolver) -> int:
    """Steps of the free-form march for the renderer's dent solver."""
    return max(MARCH_STEPS, 4 * solver.march_steps)


def march_loop_iterations(scene: MarchScene, solver: MarchSolver) -> int:
    """Loop iterations of one ray's first hit: the march and its polish, on each of the two
    shifted surfaces that bracket a dent (once without one)."""
    surfaces = 2 if scene.defect.present else 1
    return surfaces * ((march_steps(solver) + 1) + (POLISH_ITERATIONS + 1))


def march_uniforms(scene: MarchScene, context: MarchContext) -> dict[str, object]:
    """The uniforms of ``lib/freeform.glsl``."""
    return {
        "u_surface_march_steps": march_steps(context.solver),
        "u_surface_march_tol": context.solver.tolerance_for(scene.render.precision),
    }
