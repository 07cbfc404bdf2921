"""A measured or sampled height map ``y = f(x, z)`` (``surface.kind = "heightmap"``).

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

Unmeasured samples (NaN, as profilometers write them) are either filled (``fill =
"nearest"`` or ``"harmonic"``: :func:`fill_nearest`, :func:`fill_harmonic`) or masked
(``fill = "none"``, the default): a cell of the spline whose 4 x 4 footprint touches an
unmeasured sample is a hole, where the ray meets no surface it could reflect from (the
pixel is a miss, in the shader and in the oracle alike). The first-hit solve itself runs
on the harmonic fill of the map, so the holes occlude what lies behind them as the part's
unknown surface would, and the march keeps its rigorous bounds; a hit that lands in a
hole is then discarded (``base_measured`` in the shader, :meth:`HeightMapSurface.measured`
in the oracle). :meth:`HeightMapSurface.coverage` reports how the holes and the map's edge
sit against the dent.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Hashable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, cast

import numpy as np
from numpy.typing import NDArray

from glshade.components.base import SceneView, SurfaceComponent, UniformContext
from glshade.components.surface.freeform import (
    MARCH_GLSL,
    march_loop_iterations,
    march_uniforms,
)
from glshade.errors import SceneError
from glshade.params import Table, param

if TYPE_CHECKING:  # the readers are loaded with the first map read
    from glshade.components.surface.heightmap.accuracy import HeightMapKnob
    from glshade.components.surface.heightmap.readers import HeightMap

OUTSIDES = ("curtain", "flat")
#: What becomes of unmeasured (NaN) samples: masked, or filled from the measured ones.
FILLS = ("none", "nearest", "harmonic")
#: The dent's region for :meth:`HeightMapSurface.coverage`: within this many standard
#: deviations of its centre (the Mahalanobis distance of its covariance).
DENT_REACH_SIGMA = 3.0


#: The sample spacing a map may have (mm, along x and along z; an x3p's increments too):
#: from a nanometre (an interferometer's pixel is ~100 nm) to a metre.
SPACING_RANGE_MM = (1e-6, 1e3)
#: Where sample [0, 0] may lie (mm, x and z): within 10 m of the origin, the gaze point of
#: a rig whose camera stands ~0.2 m away.
ORIGIN_RANGE_MM = (-1e4, 1e4)
#: mm of height per stored unit, in magnitude: from a picometre to a metre a unit.
SCALE_RANGE_MM = (1e-9, 1e3)
#: The largest height after ``scale`` (mm, either sign): a part a metre high is beyond
#: any deflectometry rig, and the bound keeps every height, slope and curvature bound
#: finite in float32.
HEIGHT_LIMIT_MM = 1e3
#: Memory the harmonic fill takes per unmeasured sample (bytes; SuperLU's factors of the
#: 5-point Laplacian in minimum-degree order and the arrays of the unknowns, measured
#: 1.6-1.8 KiB for square holes of 2.6e5 to 4.2e6 samples): beyond the memory budget the
#: fill is refused.
HARMONIC_BYTES_PER_UNKNOWN = 2048
#: Samples per block where a pass over the map works in row blocks (8 MiB of float64
#: temporaries), so no temporary is the size of the map.
BLOCK_SAMPLES = 1 << 20


#: How far the shader's bracketing slab reaches beyond the map's lowest and highest point
#: (mm): well above float32's rounding of a hit along a 500 mm ray, far below any height
#: that matters.
SLAB_PAD_MM = 1e-4


@dataclass(frozen=True)
class MapCoverage:
    """How a height map covers the dent (:meth:`HeightMapSurface.coverage`).

    ``nan_fraction``: the share of the map's samples the file leaves unmeasured (NaN), in
    [0, 1], whatever the fill. ``nan_near_dent``: a masked cell (one whose spline touches
    an unmeasured sample; none once filled) lies within the dent's region.
    ``dent_at_edge``: the dent's region reaches the map's edge or beyond it.
    """

    nan_fraction: float
    nan_near_dent: bool
    dent_at_edge: bool


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
    #: (rows - 1, columns - 1): cell [j, i] (between samples j, j + 1 and i, i + 1) is a
    #: hole, its spline's footprint touching an unmeasured sample (all False once filled)
    holes: np.ndarray = field(repr=False)
    #: the share of the file's samples that are unmeasured (NaN), whatever the fill
    nan_fraction: float = 0.0

    @property
    def shape(self) -> tuple[int, int]:
        return self.heights.shape

    @property
    def far_corner(self) -> tuple[float, float]:
        rows, cols = self.shape
        return self.corner[0] + (cols - 1) * self.spacing[0], self.corner[1] + (
            rows - 1
        ) * self.spacing[1]


def check_heightmap(values: dict[str, Any]) -> None:
    """A height-map surface names a readable map and, unless the file carries it, a spacing;
    ``scale`` is at least :data:`SCALE_RANGE_MM`'s low end in magnitude."""
    if values.get("kind") != "heightmap":
        return
    scale = values.get("scale", 1.0)
    if abs(scale) < SCALE_RANGE_MM[0]:
        raise SceneError("surface.scale", _SCALE_ALLOWED, scale)
    if values.get("file") is None:
        raise SceneError("surface.file", 'set for kind = "heightmap" (the height map to read)')
    _grid(
        values["file"],
        values.get("scale", 1.0),
        values.get("spacing"),
        values.get("origin"),
        values.get("outside"),
        values.get("fill"),
    )


def _pair_allowed(names: str, bounds: tuple[float, float]) -> str:
    return f"two numbers {names} in [{bounds[0]:g}, {bounds[1]:g}] mm"


_SCALE_ALLOWED = (
    f"a number whose magnitude is in [{SCALE_RANGE_MM[0]:g}, {SCALE_RANGE_MM[1]:g}] "
    "(mm per stored unit)"
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
        value_type="pair", lo=SPACING_RANGE_MM[0], hi=SPACING_RANGE_MM[1], closed=True,
        allowed_text=_pair_allowed("[dx, dz]", SPACING_RANGE_MM),
    )  # fmt: skip
    origin: tuple[float, float] | None = param(
        "surface.origin", "mm", None,
        "(x, z) of sample [row 0, column 0]; unset: the map centred on the origin",
        value_type="pair", lo=ORIGIN_RANGE_MM[0], hi=ORIGIN_RANGE_MM[1], closed=True,
        allowed_text=_pair_allowed("[x, z]", ORIGIN_RANGE_MM),
    )  # fmt: skip
    scale: float = param(
        "surface.scale", "mm", 1.0,
        "mm of height per stored unit (.x3p: from the file, metres to mm); the heights it "
        f"gives must lie within ±{HEIGHT_LIMIT_MM:g} mm",
        nonzero=True, lo=-SCALE_RANGE_MM[1], hi=SCALE_RANGE_MM[1], closed=True,
        allowed_text=_SCALE_ALLOWED,
    )  # fmt: skip
    outside: str = param(
        "surface.outside", "", "curtain", "beyond the map: curtain (no surface) or flat (y = 0)",
        value_type="choice", choices=OUTSIDES, role="feature",
    )  # fmt: skip
    fill: str = param(
        "surface.fill", "", "none",
        "unmeasured (NaN) samples: none (holes: no surface there), nearest (the nearest "
        "measured sample) or harmonic (Laplace's equation over each hole)",
        value_type="choice", choices=FILLS, role="feature", flag="--fill",
    )  # fmt: skip


def heightmap_table(scene: SceneView) -> HeightMapTable:
    """The scene's surface table, as the height map reads it."""
    return cast(HeightMapTable, scene.surface)


def grid_of(scene: SceneView) -> Grid:
    s = heightmap_table(scene)
    file = cast(str, s.file)  # set: check_heightmap refuses a height map without one
    return _grid(file, s.scale, s.spacing, s.origin, s.outside, s.fill)


def _grid(
    file: str,
    scale: float,
    spacing: tuple[float, float] | None,
    origin: tuple[float, float] | None,
    outside: str | None,
    fill: str | None,
) -> Grid:
    """The render-ready grid: the map's arrays (:func:`_surface_arrays`, cached per map and
    fill) placed by ``spacing`` and ``origin`` (cheap, built on every call)."""
    from glshade.components.surface.heightmap.readers import cached_height_map  # maps only

    height_map = cached_height_map(file, float(scale))  # the same object while unchanged
    if height_map.spacing_mm is not None and spacing is None:
        spacing = height_map.spacing_mm
    if spacing is None:
        raise SceneError(
            "surface.spacing",
            f"set: {Path(file).name} carries no sample spacing (two numbers in "
            f"[{SPACING_RANGE_MM[0]:g}, {SPACING_RANGE_MM[1]:g}] mm)",
        )
    arrays = _surface_arrays(height_map, fill or "none")
    rows, cols = arrays.heights.shape
    if origin is None:  # the map centred on the origin
        origin = (-0.5 * (cols - 1) * spacing[0], -0.5 * (rows - 1) * spacing[1])
    lo, hi, curvature = _bounds(arrays.differences, spacing)
    if (outside or "curtain") == "flat":
        lo, hi = min(lo, 0.0), max(hi, 0.0)
    return Grid(
        arrays.heights,
        arrays.texture,
        (float(spacing[0]), float(spacing[1])),
        (float(origin[0]), float(origin[1])),
        lo,
        hi,
        curvature,
        Path(height_map.source).name,
        arrays.holes,
        arrays.nan_fraction,
    )


@dataclass(frozen=True, eq=False)
class _SurfaceArrays:
    """What a map and a fill give, whatever the spacing, origin and outside: the heights
    the oracle interpolates (float64, the texture's hi + lo), the texture, the hole cells,
    the share of unmeasured samples and :func:`difference_maxima` of the heights."""

    heights: np.ndarray = field(repr=False)
    texture: np.ndarray = field(repr=False)
    holes: np.ndarray = field(repr=False)
    nan_fraction: float
    differences: tuple[float, float, float, float, float]


@functools.lru_cache(maxsize=1)
def _surface_arrays(height_map: HeightMap, fill: str) -> _SurfaceArrays:
    """The arrays of ``height_map`` filled as ``fill`` says (one map's kept: the memory
    budget is one map's; maps compare by identity). Every pass over the map works in row
    blocks: the only arrays of the map's size are the fill's, the hole cells, the texture
    and the heights."""
    heights = height_map.heights
    unmeasured = np.isnan(heights)
    count = int(np.count_nonzero(unmeasured))
    holes = hole_cells(unmeasured) if fill == "none" and count else None
    del unmeasured
    if count and fill == "nearest":
        heights = fill_nearest(heights)
    elif count:  # "harmonic", and the geometry the holes of "none" occlude with
        check_harmonic_size(heights.shape, count, Path(height_map.source).name)
        heights = fill_harmonic(heights)
    if holes is None:
        holes = np.zeros((heights.shape[0] - 1, heights.shape[1] - 1), dtype=bool)
    texture = split_texture(heights, holes)
    heights = np.add(texture[..., 0], texture[..., 1], dtype=np.float64)
    return _SurfaceArrays(heights, texture, holes, count / heights.size, difference_maxima(heights))


def check_harmonic_size(shape: tuple[int, int], unknowns: int, name: str) -> None:
    """Refuse, before solving, a harmonic fill whose sparse solve
    (:data:`HARMONIC_BYTES_PER_UNKNOWN` an unmeasured sample) and map would not fit the
    memory budget together."""
    from glshade.components.surface.heightmap.readers import (
        BYTES_PER_SAMPLE,
        memory_budget_bytes,
        mib_text,
    )

    samples = shape[0] * shape[1]
    need = samples * BYTES_PER_SAMPLE + unknowns * HARMONIC_BYTES_PER_UNKNOWN
    budget = memory_budget_bytes()
    if need > budget:
        room = max(0, budget - samples * BYTES_PER_SAMPLE) // HARMONIC_BYTES_PER_UNKNOWN
        raise SceneError(
            "surface.fill",
            f'"nearest" for this map: the harmonic fill ("none" needs it too, for the '
            f"geometry its holes occlude with) must fit the memory budget "
            f"(GLSHADE_MEMORY_BUDGET_MB = {mib_text(budget)} MiB at "
            f"{HARMONIC_BYTES_PER_UNKNOWN} bytes an unmeasured sample: at most {room} with "
            f"this map; {name} has {unknowns}, {mib_text(need)} MiB with the map)",
        )


def _row_blocks(rows: int, cols: int) -> Iterator[tuple[int, int]]:
    """(start, stop) of blocks of rows of about :data:`BLOCK_SAMPLES` samples."""
    step = max(1, BLOCK_SAMPLES // max(cols, 1))
    return ((start, min(start + step, rows)) for start in range(0, rows, step))


def split_texture(heights: np.ndarray, holes: np.ndarray) -> np.ndarray:
    """The texture (rows, columns, 3) float32 of finite ``heights``: hi, lo (hi + lo: the
    doubles, to ~1e-14) and whether cell [j, i] is a hole at texel (j, i)."""
    rows, cols = heights.shape
    texture = np.zeros((rows, cols, 3), dtype=np.float32)
    for start, stop in _row_blocks(rows, cols):
        block = heights[start:stop]
        high = block.astype(np.float32)
        texture[start:stop, :, 0] = high
        texture[start:stop, :, 1] = block - high
    texture[:-1, :-1, 2] = holes
    return texture


def fill_nearest(heights: np.ndarray) -> np.ndarray:
    """``heights`` with every NaN sample replaced by the nearest measured one (Euclidean
    distance in samples; ties as SciPy's distance transform breaks them)."""
    from scipy import ndimage

    unmeasured = np.isnan(heights)
    if not unmeasured.any():
        return heights
    index = ndimage.distance_transform_edt(unmeasured, return_distances=False, return_indices=True)
    return heights[tuple(index)]


def fill_harmonic(heights: np.ndarray) -> np.ndarray:
    """``heights`` with its NaN samples solving Laplace's equation (the 5-point stencil:
    each equals the mean of its neighbours) with the measured samples as boundary values;
    at the map's edge a sample has only its neighbours inside the map (zero normal
    derivative there). A plane is reproduced exactly over holes inside the map; the fill
    stays within the range of the measured samples. One sparse solve (SciPy's SuperLU,
    the symmetric matrix in minimum-degree order: :data:`HARMONIC_BYTES_PER_UNKNOWN`);
    besides it, arrays the size of the unknowns and the filled copy."""
    from scipy import sparse
    from scipy.sparse.linalg import spsolve

    rows, cols = heights.shape
    flat = heights.ravel()
    unknown = np.flatnonzero(np.isnan(flat))
    if not len(unknown):
        return heights
    r, c = np.divmod(unknown, cols)
    n = len(unknown)
    diagonal = np.zeros(n)
    rhs = np.zeros(n)
    i_parts, j_parts = [], []
    for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        rn, cn = r + dr, c + dc
        inside = (rn >= 0) & (rn < rows) & (cn >= 0) & (cn < cols)
        diagonal += inside
        k = np.flatnonzero(inside)
        neighbour = rn[k] * cols + cn[k]
        values = flat[neighbour]
        known = ~np.isnan(values)
        np.add.at(rhs, k[known], values[known])
        i_parts.append(k[~known])
        j_parts.append(np.searchsorted(unknown, neighbour[~known]))  # its unknown's number
    i = np.concatenate(i_parts)
    j = np.concatenate(j_parts)
    own = np.arange(n)
    values = np.concatenate([diagonal, -np.ones(len(i))])
    where = (np.concatenate([own, i]), np.concatenate([own, j]))
    matrix = sparse.csc_matrix((values, where), shape=(n, n))
    filled = flat.copy()
    filled[unknown] = spsolve(matrix, rhs, permc_spec="MMD_AT_PLUS_A")
    return filled.reshape(rows, cols)


def hole_cells(unmeasured: np.ndarray) -> np.ndarray:
    """``(rows - 1, columns - 1)``: whether the spline's cell [j, i] reads an unmeasured
    sample (its 4 x 4 taps, rows j - 1 … j + 2 and columns i - 1 … i + 2, clamped to the
    map as :func:`catmull_rom` clamps them)."""
    padded = np.pad(unmeasured, 1, mode="edge")
    rows, cols = unmeasured.shape
    holes = np.zeros((rows - 1, cols - 1), dtype=bool)
    for a in range(4):
        for b in range(4):
            holes |= padded[a : a + rows - 1, b : b + cols - 1]
    return holes


def map_bounds(heights: np.ndarray, spacing: tuple[float, float]) -> tuple[float, float, float]:
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
    return _bounds(difference_maxima(heights), spacing)


def difference_maxima(heights: np.ndarray) -> tuple[float, float, float, float, float]:
    """``(lowest, highest, max|D_x|, max|D_z|, max|Δx Δz h|)`` of finite ``heights``: the
    samples' range, the largest second differences along x (columns) and z (rows) and the
    largest mixed difference; in row blocks (no temporary the size of the map)."""
    rows, cols = heights.shape
    along_x = along_z = mixed = 0.0
    for start, stop in _row_blocks(rows, cols):
        along_x = max(along_x, _max_abs(np.diff(heights[start:stop], 2, axis=1)))
        along_z = max(along_z, _max_abs(np.diff(heights[start : stop + 2], 2, axis=0)))
        pair = heights[start : stop + 1]
        mixed = max(mixed, _max_abs(np.diff(np.diff(pair, axis=0), axis=1)))
    return float(heights.min()), float(heights.max()), along_x, along_z, mixed


def _bounds(
    differences: tuple[float, float, float, float, float], spacing: tuple[float, float]
) -> tuple[float, float, float]:
    """:func:`map_bounds` from :func:`difference_maxima` and the spacing (mm)."""
    lowest, highest, along_x, along_z, mixed = differences
    dx, dz = spacing
    mid, half = 0.5 * (highest + lowest), 0.5 * (highest - lowest)
    reach = 1.5625 * half + 1e-12
    fxx = 3.75 * along_x / dx**2
    fzz = 3.75 * along_z / dz**2
    fxz = 4.5 * mixed / (dx * dz)
    curvature = max(fxx, fzz) + fxz
    return float(mid - reach), float(mid + reach), float(curvature) + 1e-12


def _max_abs(a: np.ndarray) -> float:
    return float(np.abs(a).max()) if a.size else 0.0


class HeightMapSurface(SurfaceComponent):
    name = "heightmap"
    rank = 4
    doc = "a measured or sampled height map, bicubic (Catmull-Rom) between the samples"
    table = HeightMapTable

    def features(self, scene: SceneView) -> dict[str, Hashable]:
        features: dict[str, Hashable] = {"heightmap_outside": heightmap_table(scene).outside}
        if grid_of(scene).holes.any():
            features["surface_holes"] = True  # the template asks base_measured(p)
        return features

    def glsl(self, variables: Mapping[str, Hashable]) -> tuple[str, ...]:
        return (*MARCH_GLSL, "heightmap.glsl")

    def textures(self, scene: SceneView) -> dict[str, np.ndarray]:
        return {"t_surface_heights": grid_of(scene).texture}

    def loop_iterations(self, scene: SceneView, solver: Any) -> int:
        return march_loop_iterations(scene, solver)

    def uniforms(self, scene: SceneView, context: UniformContext) -> dict[str, object]:
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
            # the slab the march brackets in, opened by SLAB_PAD_MM: a map of one height
            # (every sample 0) has a slab of no thickness, which float32 finds empty
            "u_surface_lo": grid.lo - SLAB_PAD_MM,
            "u_surface_hi": grid.hi + SLAB_PAD_MM,
            "u_surface_curvature": grid.curvature,
            **march_uniforms(scene, context),
        }

    def accuracy_knob(self) -> HeightMapKnob:
        # imported here: the knob is only run by `glshade accuracy`
        from glshade.components.surface.heightmap.accuracy import HeightMapKnob

        return HeightMapKnob()

    def second_derivatives(self, scene: SceneView) -> tuple[float, float]:
        grid = grid_of(scene)
        h = 0.25 * min(grid.spacing)
        x = np.array([-h, 0.0, h])
        along_x = self.height(scene, x, np.zeros(3))
        along_z = self.height(scene, np.zeros(3), x)
        second = [(v[0] - 2 * v[1] + v[2]) / h**2 for v in (along_z, along_x)]
        along_zz, along_xx = (0.0 if not math.isfinite(v) else float(v) for v in second)
        return along_zz, along_xx

    def describe(self, scene: SceneView) -> str:
        grid = grid_of(scene)
        rows, cols = grid.shape
        return f"height map {grid.name} ({cols}x{rows}, {grid.spacing[0]:g} mm)"

    def nan_fraction(self, scene: SceneView) -> float:
        """The share of the map's samples that the file leaves unmeasured (NaN), in [0, 1],
        whatever ``fill`` makes of them."""
        return grid_of(scene).nan_fraction

    def coverage(self, scene: SceneView) -> MapCoverage:
        """How this map covers the scene's dent: a :class:`MapCoverage`.

        The dent's region is the ellipse within :data:`DENT_REACH_SIGMA` (3) standard
        deviations of its centre, ``(p - c)^T Σ^-1 (p - c) <= 9`` with the defect's
        covariance Σ and centre c (x0, z0), in the scene's world (x, z), mm.

        - ``nan_fraction``: as :meth:`nan_fraction` (the file's share of NaN samples).
        - ``nan_near_dent``: a masked cell (``fill = "none"``: a cell of the spline whose
          footprint touches an unmeasured sample, where rays meet no surface) overlaps the
          dent's region. Always False once the map is filled (``nearest``, ``harmonic``)
          or when the scene has no dent.
        - ``dent_at_edge``: the dent's region reaches the map's rectangle's edge or lies
          partly beyond it (the dent is then not all on measured data, whether
          ``outside`` is a curtain or the plane y = 0). False when the scene has no dent.

        A caller that finds either flag True should not trust a visibility read off this
        map as the dent's own. Pure NumPy, cheap (one pass over the hole cells)."""
        grid = grid_of(scene)
        defect = scene.defect
        if not scene.active.defect.present(scene):
            return MapCoverage(grid.nan_fraction, False, False)
        centre = np.asarray(scene.active.defect.centre(scene), dtype=np.float64)[[0, 2]]
        sigma = np.array(
            [[defect.sigma_x2, defect.sigma_xz], [defect.sigma_xz, defect.sigma_z2]], float
        )
        reach = DENT_REACH_SIGMA**2
        half = DENT_REACH_SIGMA * np.sqrt(np.diag(sigma))  # the ellipse's half-extent in x, z
        (x0, z0), (x1, z1) = grid.corner, grid.far_corner
        at_edge = bool(
            centre[0] - half[0] <= x0
            or centre[0] + half[0] >= x1
            or centre[1] - half[1] <= z0
            or centre[1] + half[1] >= z1
        )
        near = _cells_meet_ellipse(
            grid, np.argwhere(grid.holes), centre, np.linalg.inv(sigma), reach
        )
        return MapCoverage(grid.nan_fraction, near, at_edge)

    # ------------------------------------------------------------------ oracle
    def domain(
        self, scene: SceneView, o: np.ndarray, d: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        n = len(d)
        if heightmap_table(scene).outside == "flat":
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

    def band_roots(
        self, scene: SceneView, o: np.ndarray, d: np.ndarray, shift: float
    ) -> list[np.ndarray]:
        grid = grid_of(scene)
        flat = heightmap_table(scene).outside == "flat"
        levels = (grid.hi, grid.lo, 0.0) if flat else (grid.hi, grid.lo)
        with np.errstate(divide="ignore", invalid="ignore"):
            return [
                np.where(d[:, 1] != 0, (level + shift - o[:, 1]) / d[:, 1], np.nan)
                for level in levels
            ]

    def height(self, scene: SceneView, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        return self._evaluate(scene, x, z)[0]

    def measured(self, scene: SceneView, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        """False in the holes: cells whose spline reads an unmeasured sample (``fill =
        "none"``); a hit there is a miss. The cell of (x, z) is found as the spline finds
        it (clamped to the map); beyond a ``flat`` map's edge the plane is measured."""
        grid = grid_of(scene)
        x, z = np.broadcast_arrays(np.asarray(x, np.float64), np.asarray(z, np.float64))
        if not grid.holes.any():
            return np.ones(x.shape, dtype=bool)
        rows, cols = grid.shape
        finite = np.isfinite(x) & np.isfinite(z)  # no point (NaN): nothing to discard
        x, z = np.where(finite, x, grid.corner[0]), np.where(finite, z, grid.corner[1])
        u = np.clip((x - grid.corner[0]) / grid.spacing[0], 0.0, cols - 1.0)
        v = np.clip((z - grid.corner[1]) / grid.spacing[1], 0.0, rows - 1.0)
        i = np.clip(np.floor(u), 0, cols - 2).astype(np.int64)
        j = np.clip(np.floor(v), 0, rows - 2).astype(np.int64)
        measured = ~grid.holes[j, i] | ~finite
        if heightmap_table(scene).outside == "flat":
            measured |= ~self._inside(grid, x, z)
        return measured

    def outside(self, scene: SceneView, x: np.ndarray, z: np.ndarray) -> np.ndarray:
        if heightmap_table(scene).outside == "flat":
            return np.zeros(np.broadcast(x, z).shape, dtype=bool)
        return ~self._inside(
            grid_of(scene), *np.broadcast_arrays(np.asarray(x, float), np.asarray(z, float))
        )

    def normal(
        self, scene: SceneView, x: np.ndarray, z: np.ndarray, dx: np.ndarray, dz: np.ndarray
    ) -> np.ndarray:
        _, fx, fz = self._evaluate(scene, x, z)
        return np.stack([-(fx + dx), np.ones_like(fx), -(fz + dz)], axis=-1)

    @staticmethod
    def _inside(grid: Grid, x: np.ndarray, z: np.ndarray) -> NDArray[np.bool_]:
        (x0, z0), (x1, z1) = grid.corner, grid.far_corner
        return (x >= x0) & (x <= x1) & (z >= z0) & (z <= z1)

    def _evaluate(
        self, scene: SceneView, x: np.ndarray, z: np.ndarray
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
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
        if heightmap_table(scene).outside == "flat":
            inside = self._inside(grid, x, z)
            f, fx, fz = (np.where(inside, v, 0.0) for v in (f, fx, fz))
        return f, fx, fz


def _cells_meet_ellipse(
    grid: Grid,
    cells: np.ndarray,
    centre: NDArray[np.float64],
    inverse: NDArray[np.float64],
    reach: float,
) -> bool:
    """Whether any of the cells ``[j, i]`` (rectangles between samples) meets the ellipse
    ``(p - centre)^T inverse (p - centre) <= reach``: the centre lies in a cell, or the
    quadratic's minimum along one of a cell's four edges is within reach."""
    if not len(cells):
        return False
    j, i = cells[:, 0].astype(float), cells[:, 1].astype(float)
    (dx, dz), (x0, z0) = grid.spacing, grid.corner
    left, right = x0 + i * dx, x0 + (i + 1) * dx
    bottom, top = z0 + j * dz, z0 + (j + 1) * dz
    cx, cz = centre
    if np.any((left <= cx) & (cx <= right) & (bottom <= cz) & (cz <= top)):
        return True
    corners = (
        np.stack([left, bottom], -1),
        np.stack([right, bottom], -1),
        np.stack([right, top], -1),
        np.stack([left, top], -1),
    )
    for k in range(4):
        a, b = corners[k] - centre, corners[(k + 1) % 4] - centre
        e = b - a
        ee = np.einsum("ni,ij,nj->n", e, inverse, e)
        s = np.clip(-np.einsum("ni,ij,nj->n", a, inverse, e) / ee, 0.0, 1.0)
        p = a + s[:, None] * e
        if np.any(np.einsum("ni,ij,nj->n", p, inverse, p) <= reach):
            return True
    return False


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


def catmull_rom(
    heights: np.ndarray, u: np.ndarray, v: np.ndarray
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
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
