"""How wide a reflection lobe lands on the emitter (the lobe warning of every glossy
reflection model).

A lobe of angular standard deviation ``s`` (rad, of the reflected direction) blurs the
stripes by ``s · |∂v/∂α|`` mm on the emitter, where ``∂v/∂α`` is how fast the emitter
coordinate ``v`` moves as the mirror ray turns. The blur of a Gaussian of std ``b``
keeps ``exp(-2π² b²/P²)`` of a period-``P`` pattern's first harmonic; the footprint
``2b`` (the lobe's ±1σ width) beyond half a period keeps less than 29 %: the stripes
wash out. ``docs/physics.md`` relates exponent, period and distance.
"""

from __future__ import annotations

import numpy as np

from glshade.scene import Scene

#: Small rotation of the mirror ray used to differentiate ``v`` (rad).
_DALPHA = 1e-5


def footprint_mm(scene: Scene, lobe_std_rad: float, screen_axis: int = 1) -> float | None:
    """The lobe's ±1σ width along the screen coordinate ``screen_axis`` (1: ``v``, 0: ``u``) on the
    emitter (mm) for the image's centre pixel, or None where the centre ray misses the
    surface or the emitter."""
    from glshade.oracle.tracer import first_hit  # a lobe only: most scenes never trace here

    cam = scene.camera
    rows, cols = (
        slice(cam.height // 2, cam.height // 2 + 1),
        slice(cam.width // 2, cam.width // 2 + 1),
    )
    origin, directions = cam.pixel_rays(rows, cols)
    d = np.asarray(directions, np.float64).reshape(-1, 3)[:1]
    _, points, normals, valid = first_hit(
        scene, np.asarray(origin, np.float64).reshape(-1, 3)[:1], d
    )
    if not valid.reshape(-1)[0]:
        return None
    d = d / np.linalg.norm(d)
    n = normals.reshape(-1, 3)[0]
    r = d[0] - 2.0 * (d[0] @ n) * n
    axis = np.cross(r, n)  # turning r about this axis moves it in the plane of incidence
    if np.linalg.norm(axis) < 1e-12:
        axis = np.cross(r, [1.0, 0.0, 0.0])
    axis /= np.linalg.norm(axis)
    spread = 0.0
    for turn in (axis, np.cross(r, axis)):  # in and across the plane of incidence
        turned = np.stack([r + s * _DALPHA * np.cross(turn, r) for s in (-1.0, 1.0)])
        start = np.repeat(points.reshape(-1, 3)[:1], 2, 0)
        landed = scene.active.emitter.coordinates(scene, start, turned)
        if not landed[2].all():
            return None
        coordinate = landed[screen_axis]
        spread = max(spread, abs(coordinate[1] - coordinate[0]) / (2 * _DALPHA))
    return 2.0 * lobe_std_rad * spread
