"""What the free-form surfaces (a formula, a height map) share: the uniforms of the
library's free-form march (``lib/freeform.glsl``)."""

from __future__ import annotations

#: Steps of the first-hit march (it converges from above in a few; skimming rays take more).
MARCH_STEPS = 256
#: The GLSL every free-form surface puts before its own.
MARCH_GLSL = ("lib/march.glsl", "lib/freeform.glsl")


def march_uniforms(scene, context) -> dict[str, object]:
    """The uniforms of ``lib/freeform.glsl``."""
    return {
        "u_surface_march_steps": max(MARCH_STEPS, 4 * context.solver.march_steps),
        "u_surface_march_tol": context.solver.tolerance_for(scene.render.precision),
    }
