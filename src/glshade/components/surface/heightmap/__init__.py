"""A measured or sampled height map ``y = f(x, z)`` (SPEC §8.1 ``kind = "heightmap"``).

The samples ``heights[row, column]`` (rows along +z, columns along +x, ``spacing`` mm
apart, sample [0, 0] at ``origin``; read by :mod:`.readers` from .npy, .x3p,
float TIFF or 16-bit PNG) are interpolated by the bicubic Catmull-Rom spline: it passes
through every sample, is C¹ (continuous slopes: continuous normals, so no facets in the
stripes) and has exact gradients, the same in the shader (``heightmap.glsl``,
16 ``texelFetch`` of a float texture) and in the NumPy oracle here. Beyond the map the
surface is either absent (``outside = "curtain"``: those rays miss) or the plane y = 0
(``"flat"``).

First hit: the library's ``freeform.glsl``, bracketed by the slab [lo, hi] and driven by a bound
K on ``|f''|``, both rigorous for the spline (:func:`map_bounds`).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from glshade.components.base import SurfaceComponent
from glshade.components.surface.freeform import (
    MARCH_GLSL,
    march_loop_iterations,
    march_uniforms,
)
from glshade.components.surface.heightmap.readers import cached_height_map
from glshade.errors import SceneError
from glshade.params import Table, param

OUTSIDES = ("curtain", "flat")


@dataclass(frozen=True, eq=False)
class Grid:
    """A height map ready to render: heights in mm (float64 for the oracle; for the
    texture split into float32 pairs hi + lo, so fp64 renders see the doubles), the
    spacing and the world (x, z) of sample [0, 0], and its bounds."""

    heights: np.ndarray = field(repr=False)
    texture: np.ndarray = field(repr=False)
    spacing: tuple[float, float]
    corner: tuple[float, float]
    lo: float
    hi: float
    curvature: float
    name: str

    @property
    def shape(self) -> tuple[int, int]:
        return self.heights.shape

    @property
    def far_corner(self) -> tuple[float, float]:
        rows, cols = self.shape
        return self.corner[0] + (cols - 1) * self.spacing[0], self.corner[1] + (
            rows - 1
        ) * self.spacing[1]


def check_heightmap(values: dict) -> None:
    """A height-map surface names a readable map and, unless the file carries it, a spacing."""
    if values.get("kind") != "heightmap":
        return
    if values.get("file") is None:
        raise SceneError("surface.file", 'set for kind = "heightmap" (the height map to read)')
    _grid(
        values["file"],
        values.get("scale", 1.0),
        values.get("spacing"),
        values.get("origin"),
        values.get("outside"),
    )


@dataclass(frozen=True)
class HeightMapTable(Table):
    """The height map's file and how its samples sit in the world."""

    table = "surface"
    table_checks = (check_heightmap,)

    file: str | None = param(
        "surface.file", "", None,
        "the height map: .npy, .x3p (ISO 25178-72), float .tif/.tiff or 16-bit .png",
        value_type="path", role="feature",
    )  # fmt: skip
    spacing: tuple[float, float] | None = param(
        "surface.spacing", "mm", None,
        "sample spacing along x (columns) and z (rows); .x3p carries its own",
        value_type="pair", lo=0.0,
    )  # fmt: skip
    origin: tuple[float, float] | None = param(
        "surface.origin", "mm", None,
        "(x, z) of sample [row 0, column 0]; unset: the map centred on the origin",
        value_type="pair",
    )  # fmt: skip
    scale: float = param(
        "surface.scale", "mm", 1.0,
        "mm of height per stored unit (.x3p: from the file, metres to mm)", nonzero=True,
    )  # fmt: skip
    outside: str = param(
        "surface.outside", "", "curtain", "beyond the map: curtain (no surface) or flat (y = 0)",
        value_type="choice", choices=OUTSIDES, role="feature",
    )  # fmt: skip


def grid_of(scene) -> Grid:
    s = scene.surface
    return _grid(s.file, s.scale, s.spacing, s.origin, s.outside)


def _grid(file, scale, spacing, origin, outside) -> Grid:
    height_map = cached_height_map(
        file, float(scale)
    )  # the same object while the file is unchanged
    return _build(height_map, spacing, origin, outside or "curtain")


@functools.lru_cache(maxsize=8)
def _build(height_map, spacing, origin, outside: str) -> Grid:
    """The render-ready grid of a map (cached per map object: maps compare by identity)."""
    file = height_map.source
    heights = np.asarray(height_map.heights, dtype=np.float64)
    if height_map.spacing_mm is not None and spacing is None:
        spacing = height_map.spacing_mm
    if spacing is None:
        raise SceneError(
            "surface.spacing",
            f"set: {Path(file).name} carries no sample spacing (two numbers > 0, mm)",
        )
    rows, cols = heights.shape
    if origin is None:  # the map centred on the origin
        origin = (-0.5 * (cols - 1) * spacing[0], -0.5 * (rows - 1) * spacing[1])
    lo, hi, curvature = map_bounds(heights, spacing)
    if outside == "flat":
        lo, hi = min(lo, 0.0), max(hi, 0.0)
    high = heights.astype(np.float32)
    texture = np.stack(
        [high, (heights - high).astype(np.float32)], axis=-1
    )  # hi + lo: the doubles, to ~1e-14
    heights = (
        high.astype(np.float64) + texture[..., 1]
    )  # the oracle interpolates what the shader reads
    return Grid(
        heights,
        texture,
        (float(spacing[0]), float(spacing[1])),
        (float(origin[0]), float(origin[1])),
        lo,
        hi,
        curvature,
        Path(file).name,
    )


def map_bounds(heights: np.ndarray, spacing) -> tuple[float, float, float]:
    """``(lo, hi, K)`` for the Catmull-Rom spline of ``heights``: it lies in [lo, hi] and
    ``|f''|`` along any horizontal unit direction is at most K (1/mm).

    - Range: the spline is a weighted sum of 16 samples whose weights sum to 1 with
      ``Σ|w| <= 1.25`` per axis, so it stays within ``1.25² = 1.5625`` half-ranges of the
      samples' mid-range.
    - Curvature: along one axis the spline's second derivative is linear on a cell and
      equals ``2 D1 - D2`` and ``2 D2 - D1`` at its ends (``D`` the second differences),
      so ``|f_xx| <= 3 max|D_x| · 1.25 / dx²`` (the other axis' weights), the same for z;
      the mixed derivative is a product of first-derivative weights (``Σ|w'| <= 1.5`` per
      axis at most) on the mixed differences: ``|f_xz| <= 2.25 · 2 max|Δx Δz h| / (dx dz)``.
      The Hessian's largest |eigenvalue| is bounded by Gershgorin's row sums.
    """
    dx, dz = spacing
    mid, half = 0.5 * (heights.max() + heights.min()), 0.5 * (heights.max() - heights.min())
    reach = 1.5625 * half + 1e-12
    fxx = 3.75 * _max_abs(np.diff(heights, 2, axis=1)) / dx**2
    fzz = 3.75 * _max_abs(np.diff(heights, 2, axis=0)) / dz**2
    fxz = 4.5 * _max_abs(np.diff(np.diff(heights, axis=0), axis=1)) / (dx * dz)
    curvature = max(fxx, fzz) + fxz
    return float(mid - reach), float(mid + reach), float(curvature) + 1e-12


def _max_abs(a: np.ndarray) -> float:
    return float(np.abs(a).max()) if a.size else 0.0


class HeightMapSurface(SurfaceComponent):
    name = "heightmap"
    rank = 4
    doc = "a measured or sampled height map, bicubic (Catmull-Rom) between the samples"
    table = HeightMapTable

    def features(self, scene):
        return {"heightmap_outside": scene.surface.outside}

    def glsl(self, variables):
        return (*MARCH_GLSL, "heightmap.glsl")

    def textures(self, scene):
        return {"t_surface_heights": grid_of(scene).texture}

    def loop_iterations(self, scene, solver):
        return march_loop_iterations(scene, solver)

    def uniforms(self, scene, context):
        grid = grid_of(scene)
        rows, cols = grid.shape
        corner = (
            grid.corner[0] - float(context.origin[0]),
            grid.corner[1] - float(context.origin[2]),
        )
        return {
            "u_surface_corner": corner,
            "u_surface_spacing": grid.spacing,
            "u_surface_size": (cols, rows),
            "u_surface_lo": grid.lo,
            "u_surface_hi": grid.hi,
            "u_surface_curvature": grid.curvature,
            **march_uniforms(scene, context),
        }

    def accuracy_knob(self):
        # imported here: the knob is only run by `glshade accuracy`
        from glshade.components.surface.heightmap.accuracy import HeightMapKnob

        return HeightMapKnob()

    def second_derivatives(self, scene):
        grid = grid_of(scene)
        h = 0.25 * min(grid.spacing)
        x = np.array([-h, 0.0, h])
        along_x = self.height(scene, x, np.zeros(3))
        along_z = self.height(scene, np.zeros(3), x)
        second = [(v[0] - 2 * v[1] + v[2]) / h**2 for v in (along_z, along_x)]
        return tuple(0.0 if not math.isfinite(v) else float(v) for v in second)

    def describe(self, scene):
        grid = grid_of(scene)
        rows, cols = grid.shape
        return f"height map {grid.name} ({cols}x{rows}, {grid.spacing[0]:g} mm)"

    # ------------------------------------------------------------------ oracle
    def domain(self, scene, o, d):
        n = len(d)
        if scene.surface.outside == "flat":
            return np.full(n, -np.inf), np.full(n, np.inf)
        grid = grid_of(scene)
        t_in, t_out = np.full(n, -np.inf), np.full(n, np.inf)
        for axis, lo, hi in (
            (0, grid.corner[0], grid.far_corner[0]),
            (2, grid.corner[1], grid.far_corner[1]),
        ):
            with np.errstate(divide="ignore", invalid="ignore"):
                a, b = (lo - o[:, axis]) / d[:, axis], (hi - o[:, axis]) / d[:, axis]
            parallel = d[:, axis] == 0
            inside = (o[:, axis] >= lo) & (o[:, axis] <= hi)
            a = np.where(parallel, np.where(inside, -np.inf, np.nan), a)
            b = np.where(parallel, np.where(inside, np.inf, np.nan), b)
            t_in, t_out = np.fmax(t_in, np.minimum(a, b)), np.fmin(t_out, np.maximum(a, b))
        empty = ~(t_out >= t_in)
        return np.where(empty, np.nan, t_in), np.where(empty, np.nan, t_out)

    def band_roots(self, scene, o, d, shift):
        grid = grid_of(scene)
        levels = (grid.hi, grid.lo, 0.0) if scene.surface.outside == "flat" else (grid.hi, grid.lo)
        with np.errstate(divide="ignore", invalid="ignore"):
            return [
                np.where(d[:, 1] != 0, (level + shift - o[:, 1]) / d[:, 1], np.nan)
                for level in levels
            ]

    def height(self, scene, x, z):
        return self._evaluate(scene, x, z)[0]

    def outside(self, scene, x, z):
        if scene.surface.outside == "flat":
            return np.zeros(np.broadcast(x, z).shape, dtype=bool)
        return ~self._inside(
            grid_of(scene), *np.broadcast_arrays(np.asarray(x, float), np.asarray(z, float))
        )

    def normal(self, scene, x, z, dx, dz):
        _, fx, fz = self._evaluate(scene, x, z)
        return np.stack([-(fx + dx), np.ones_like(fx), -(fz + dz)], axis=-1)

    @staticmethod
    def _inside(grid: Grid, x, z):
        (x0, z0), (x1, z1) = grid.corner, grid.far_corner
        return (x >= x0) & (x <= x1) & (z >= z0) & (z <= z1)

    def _evaluate(self, scene, x, z):
        """``(f, f_x, f_z)`` of the spline at (x, z) (mm, any shape): clipped to the map's
        edge for a curtain (the tracer stays in the domain), 0 beyond it for a flat."""
        grid = grid_of(scene)
        x, z = np.broadcast_arrays(np.asarray(x, np.float64), np.asarray(z, np.float64))
        f, fx, fz = catmull_rom(
            grid.heights,
            (x - grid.corner[0]) / grid.spacing[0],
            (z - grid.corner[1]) / grid.spacing[1],
        )
        fx, fz = fx / grid.spacing[0], fz / grid.spacing[1]
        if scene.surface.outside == "flat":
            inside = self._inside(grid, x, z)
            f, fx, fz = (np.where(inside, v, 0.0) for v in (f, fx, fz))
        return f, fx, fz


def _weights(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Catmull-Rom weights of the 4 taps and their derivatives, (…, 4) each."""
    t2, t3 = t * t, t * t * t
    w = np.stack(
        [
            0.5 * (-t3 + 2 * t2 - t),
            0.5 * (3 * t3 - 5 * t2 + 2),
            0.5 * (-3 * t3 + 4 * t2 + t),
            0.5 * (t3 - t2),
        ],
        axis=-1,
    )
    dw = np.stack(
        [
            0.5 * (-3 * t2 + 4 * t - 1),
            0.5 * (9 * t2 - 10 * t),
            0.5 * (-9 * t2 + 8 * t + 1),
            0.5 * (3 * t2 - 2 * t),
        ],
        axis=-1,
    )
    return w, dw


def catmull_rom(heights: np.ndarray, u: np.ndarray, v: np.ndarray):
    """The spline and its grid-unit gradient at grid coordinates (u = column, v = row),
    clamped to the map (edge samples repeated for the outer taps)."""
    rows, cols = heights.shape
    u = np.clip(u, 0.0, cols - 1.0)
    v = np.clip(v, 0.0, rows - 1.0)
    i = np.clip(np.floor(u), 0, cols - 2).astype(np.int64)
    j = np.clip(np.floor(v), 0, rows - 2).astype(np.int64)
    wu, dwu = _weights(u - i)
    wv, dwv = _weights(v - j)
    taps = np.arange(-1, 3)
    c = np.clip(i[..., None] + taps, 0, cols - 1)
    r = np.clip(j[..., None] + taps, 0, rows - 1)
    block = heights[r[..., :, None], c[..., None, :]]  # (…, 4 rows, 4 columns)
    f = np.einsum("...a,...ab,...b->...", wv, block, wu)
    fu = np.einsum("...a,...ab,...b->...", wv, block, dwu)
    fv = np.einsum("...a,...ab,...b->...", dwv, block, wu)
    return f, fu, fv


COMPONENTS = (HeightMapSurface,)
