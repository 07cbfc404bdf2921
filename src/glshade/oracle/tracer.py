"""A NumPy float64 backward ray tracer: the test oracle for the GLSL renderer.

The tracer is generic: each component of the scene (:mod:`glshade.components`) brings
its own float64 oracle (the surface its domain, band roots, height and normal; the
defect its depth, gradient, band and breakpoints; the camera its rays; the emitter where
rays land and its radiance; the reflection model its pixel value). What follows is the
method as the built-in components implement it.

Written from the scene conventions alone (no shader code was consulted), it traces one ray per
pixel sample through the pinhole, finds the first crossing of the height field
``y = f(x, z) + D(x, z)`` from above, reflects about the analytic normal, intersects the
emitter plane and evaluates the stripe radiance. Every length is in mm. Speed matters
less than correctness: everything is vectorised over rays, loops run only over
iteration counts and chunks of rays.

Method
------
*First hit.* Along a ray ``P(t) = o + t d`` (``|d| = 1``, ``t`` in mm) the gap
``g(t) = y(t) - f(x(t), z(t)) - D(x(t), z(t))`` is positive above the surface. The hit is
the first ``t > 0`` inside the surface's domain where ``g`` changes sign from ``+`` to
``-``; when the first sign change goes from ``-`` to ``+`` (the ray meets the back of
the shell, e.g. the outside of a deep concave bowl) the pixel is a miss. The search:

1. The domain (``|x| <= |R|``, ``|z| <= |R|`` or ``x² + z² <= R²``) gives an interval
   ``[t_in, t_out]`` (ray/slab or ray/circle, stable quadratic roots).
2. ``D`` lies in ``[lo, hi] = [min(0, -dmax), max(0, -dmax)]``, so ``g`` can vanish only
   where the base gap ``g0 = y - f`` is in ``[lo, hi]``. The roots of ``g0 = lo - eps``
   and ``g0 = hi + eps`` (``eps = 1e-9`` mm) are ray intersections with the base surface
   shifted along ``y``: a plane, or a circle/sphere of radius ``|R|`` whose centre moves
   with the shift (stable quadratic, discriminant in the ``r² - |perp|²`` form of Ray
   Tracing Gems ch. 7). Between consecutive roots ``g`` has a known sign, so every
   crossing lies in a "band" segment bounded by these breakpoints. The ray's entries
   into the defect's Mahalanobis ellipses ``q = 1, 9, 72.25`` are breakpoints too (beyond
   ``q = 72.25`` the defect is below ``2e-16 |dmax|``).
3. Every segment between breakpoints gets ``64`` uniform samples of ``g`` whatever its
   length, so short band segments are sampled densely. The first sign change between
   samples brackets the hit. Before it, every interior local minimum of the samples is
   refined by golden-section search, which finds dips below the surface narrower than
   the sample spacing (grazing rays over a bump); a negative minimum moves the bracket
   there.
4. Bisection on ``g`` until the bracket is one ulp wide.
5. A hit where the surface has no data (:meth:`SurfaceComponent.measured`: a height
   map's holes) is a miss.

*Normal.* ``n ∝ (-h_x, 1, -h_z)`` for ``h = f + D``; for curved kinds it is multiplied
through by ``w = sqrt(R² - ρ²)`` so it stays finite (horizontal) at a sphere's
silhouette. ``f`` is evaluated in the sag form ``-sign(R) ρ² / (|R| + w)`` with
``w = sqrt((|R| - ρ)(|R| + ρ))``, which loses no digits near the apex or the rim.

*Emitter.* Mirror direction ``r = d - 2 (d·n) n``; the plane is hit at ``t_e > 0`` with
``r·n_E < 0``; ``(u, v)`` are the in-plane coordinates, valid within ``half_size``.
Radiance: the Gaussian stripes summed over every stripe within ``10σ`` (or, when more
than 64 stripes overlap, the exact Poisson-summed series, which converges in a few terms).

*Blinn-Phong.* ``∫ L(Q(l)) w(l) dω_l / ∫ w(l) dω_l`` with ``w = max(n·h, 0)^n``,
``h = normalise(l + wo)``, by brute-force midpoint quadrature. The integral is taken over
the half vector rather than over ``l``: the exact change of variables ``l = 2 (wo·h) h -
wo``, ``dω_l = 4 (wo·h) dω_h`` (``wo·h > 0``: each ``l`` once) turns the lobe into an
isotropic one, ``(n·h)^n``, of angular std ``1/sqrt(n)`` around the normal, whatever the
incidence. Over ``l`` the integrand is singular at ``l = d`` (``h`` undefined; the lobe's
width across the plane of incidence shrinks to zero there), which on an ``l``-space grid
costs ~1e-4 at 5° elevation and ``n = 1e3``; in ``h`` the same point is the smooth edge
``wo·h = 0`` where the weight fades linearly. The grid is gnomonic,
``h ∝ n + a e1 + b e2`` (``e1`` in the plane of incidence), ``dω_h = da db /
(1 + a² + b²)^{3/2}``, over ``|a|, |b| <= tan(8/sqrt(n))``; its step resolves the lobe
(2 points per std) and the stripes (``v`` changes by at most ``σ/1.5`` per step, with
``∂v/∂a``, ``∂v/∂b`` measured per pixel on a coarse grid). The denominator counts every
direction (no horizon clipping), so a uniform emitter gives 1 and the uv/mask of a
Blinn-Phong frame are the mirror ray's.

Error budget
------------
* Hit distance: bisection to one ulp of ``t`` (about 6e-14 mm at t = 250 mm); the hit
  point then lies within ~1e-13 mm of the height field (``|y - h|`` is evaluated with
  relative error ~1e-16 in the sag form).
* Normal: analytic; the hit-point error moves it by ~1e-13 mm / R ~ 1e-15 rad (more
  within ~1e-6 mm of a sphere's silhouette, where ``w`` is ill-conditioned in ``ρ``);
  ``(u, v)`` then carry ~(distance to emitter) x 2e-15 ~ 1e-12 mm.
* Completeness of the root search: a crossing is missed only if ``g`` dips below zero
  over a stretch shorter than the local sample spacing (``segment length / 64``) *and*
  the dip is not next to a sampled local minimum of ``g`` (golden-section refinement
  assumes one minimum between three samples). Such rays graze the surface to within
  ~(spacing)² x curvature, well below a pixel's footprint; their outcome is ill-posed
  in any finite precision.
* Radiance: exact up to dropped terms below ``exp(-50)``.
* Blinn-Phong: box truncation below ``exp(-32)`` of the lobe; midpoint quadrature of
  resolved Gaussian-like integrands converges spectrally (measured against an
  independent ``l``-space quadrature: ~1e-12), except where the lobe straddles the
  emitter's edge (a discontinuity: O(grid step) there) or reaches ``wo·h = 0`` at
  grazing incidence with small ``n`` (a kink: ~6e-8 at 5° elevation, ``n = 1e3``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from glshade.components.base import Active
from glshade.errors import GlshadeError
from glshade.frame import Frame, normalize_outputs
from glshade.scene import Camera, Defect, Emitter, Scene, Surface

#: Uniform samples of the gap per segment between breakpoints.
_SAMPLES_PER_SEGMENT = 64
#: Rays traced at once (bounds the (rays x samples) work arrays).
_CHUNK_RAYS = 2048
#: Margin (mm) added to the band [lo, hi] so that its ends bracket a zero-depth defect.
_BAND_MARGIN_MM = 1e-9
#: Golden-section iterations for hidden dips (bracket shrinks by 0.618^k).
_GOLDEN_ITERATIONS = 64


# ============================================================================ the pieces
def pixel_rays(
    camera: Camera, rows: slice | None = None, cols: slice | None = None, supersample: int = 1
):
    """Camera rays: ``(origin, directions)``, float64 (the camera's chief rays:
    :meth:`Camera.pixel_rays`). ``rows``/``cols`` select pixels of the full sensor (row 0
    at the top)."""
    scene = Scene(camera=camera)
    return scene.active.camera.pixel_rays(scene, rows, cols, supersample)


def radiance(emitter: Emitter, v) -> np.ndarray:
    """The emitter's radiance at ``v`` (mm): the emitter component's oracle."""
    scene = Scene(emitter=emitter)
    return scene.active.emitter.radiance(scene, v)


def emitter_coordinates(scene: Scene, points, directions):
    """Where rays ``points + t r`` (mm) meet the emitter: ``(u, v, valid)``, NaN where not
    valid (the emitter component's oracle)."""
    return scene.active.emitter.coordinates(scene, points, directions)


def surface_height(surface: Surface, defect: Defect, x, z) -> np.ndarray:
    """Height ``y = f(x, z) + D(x, z)`` (mm) of the surface at ``(x, z)`` (mm); NaN where
    the base surface does not exist."""
    scene = Scene(surface=surface, defect=defect)
    parts = scene.active
    x = np.asarray(x, dtype=np.float64)
    z = np.asarray(z, dtype=np.float64)
    d = parts.defect.depth(scene, x, z)
    height = parts.surface.height(scene, x, z) + d
    return np.where(parts.surface.outside(scene, x, z), np.nan, height)


def _gap(scene: Scene, parts: Active, o: np.ndarray, d: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``g(t) = y - f - D`` (mm) along rays ``o + t d``; ``o, d`` (N, 3), ``t`` (N,) or
    (N, M). The surface's height is clipped to its domain (samples there are inside up
    to roundoff)."""
    ex = (slice(None),) + (None,) * (t.ndim - 1)
    x = o[:, 0][ex] + t * d[:, 0][ex]
    y = o[:, 1][ex] + t * d[:, 1][ex]
    z = o[:, 2][ex] + t * d[:, 2][ex]
    g = y - parts.defect.depth(scene, x, z)
    return g - parts.surface.height(scene, x, z)


def _normals(scene: Scene, parts: Active, x: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Unit normals (…, 3) of ``h = f + D``, from the surface's unnormalised normal."""
    dx, dz = parts.defect.gradient(scene, x, z)
    n = parts.surface.normal(scene, x, z, dx, dz)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


# ============================================================================ solvers
def _bisect(scene, parts, o, d, ta, tb):
    """Shrink ``[ta, tb]`` with ``g(ta) > 0 >= g(tb)`` to adjacent floats; returns its
    midpoint (mm)."""
    ta = ta.copy()
    tb = tb.copy()
    for _ in range(2200):  # a hard bound; ~60 iterations reach one ulp
        tm = 0.5 * (ta + tb)
        live = (tm > ta) & (tm < tb)
        if not live.any():
            break
        pos = _gap(scene, parts, o, d, tm) > 0.0
        ta = np.where(live & pos, tm, ta)
        tb = np.where(live & ~pos, tm, tb)
    return ta + 0.5 * (tb - ta)


def _golden_minimum(scene, parts, o, d, a, b):
    """Golden-section search for the minimum of ``g`` on ``[a, b]`` (per ray); returns
    ``(t_min, g_min)``, stopping early for rays where a negative value is found."""
    phi = (math.sqrt(5.0) - 1.0) / 2.0
    c = b - phi * (b - a)
    e = a + phi * (b - a)
    gc = _gap(scene, parts, o, d, c)
    ge = _gap(scene, parts, o, d, e)
    best_t = np.where(gc < ge, c, e)
    best_g = np.minimum(gc, ge)
    for _ in range(_GOLDEN_ITERATIONS):
        if (best_g < 0.0).all():
            break
        left = gc < ge  # the minimum lies in [a, e]
        b = np.where(left, e, b)
        a = np.where(left, a, c)
        new = np.where(left, b - phi * (b - a), a + phi * (b - a))
        gn = _gap(scene, parts, o, d, new)
        c, e, gc, ge = (
            np.where(left, new, e),
            np.where(left, c, new),
            np.where(left, gn, ge),
            np.where(left, gc, gn),
        )
        better = gn < best_g
        best_t = np.where(better, new, best_t)
        best_g = np.where(better, gn, best_g)
    return best_t, best_g


def _first_hit_rays(scene: Scene, o: np.ndarray, d: np.ndarray):
    """First crossing from above for rays ``o + t d`` (``o, d``: (N, 3), ``|d| = 1``).
    Returns ``(t, valid)``; ``t`` in mm, NaN where invalid."""
    parts = scene.active
    bp, t_stop, empty = _breakpoints(scene, parts, o, d)
    k = _SAMPLES_PER_SEGMENT
    frac = np.arange(k, dtype=np.float64) / k
    seg_lo, seg_hi = bp[:, :-1], bp[:, 1:]
    ts = (seg_lo[:, :, None] + (seg_hi - seg_lo)[:, :, None] * frac).reshape(len(d), -1)
    ts = np.concatenate([ts, t_stop[:, None]], axis=1)
    g = _gap(scene, parts, o, d, ts)
    ta, tb, hit, limit = _first_sign_change(ts, g, empty)
    _hidden_dips(scene, parts, o, d, ts, g, limit, empty, (ta, tb, hit))
    t = np.full(len(d), np.nan)
    if hit.any():
        t[hit] = _bisect(scene, parts, o[hit], d[hit], ta[hit], tb[hit])
        p = o[hit] + t[hit, None] * d[hit]
        measured = parts.surface.measured(scene, p[:, 0], p[:, 2])
        if not measured.all():  # a hole in the surface's data: no surface to reflect
            lost = np.flatnonzero(hit)[~measured]
            hit[lost] = False
            t[lost] = np.nan
    return t, hit


def _breakpoints(scene: Scene, parts: Active, o: np.ndarray, d: np.ndarray):
    """The sorted breakpoints ``(N, K)`` of each ray's search (domain ends, band roots,
    the defect's breakpoints), its end ``t_stop`` and whether its domain is ``empty``."""
    t_in, t_out = parts.surface.domain(scene, o, d)
    t_start = np.maximum(t_in, 0.0)
    empty = ~(t_out >= t_start)  # also NaN (no domain)
    lo, hi = parts.defect.band(scene)
    roots = parts.surface.band_roots(scene, o, d, hi + _BAND_MARGIN_MM)
    roots = roots + parts.surface.band_roots(scene, o, d, lo - _BAND_MARGIN_MM)
    roots += parts.defect.breakpoints(scene, o, d)
    bp = np.stack(roots, axis=1)
    finite = np.isfinite(bp)
    last_root = np.max(np.where(finite, bp, -np.inf), axis=1)
    t_stop = np.where(np.isfinite(t_out), t_out, last_root)
    t_stop = np.where(empty, t_start, np.maximum(t_stop, t_start))
    t_start = np.where(empty, 0.0, t_start)
    t_stop = np.where(empty, 0.0, t_stop)
    bp = np.clip(np.where(finite, bp, t_stop[:, None]), t_start[:, None], t_stop[:, None])
    bp = np.sort(np.concatenate([t_start[:, None], bp, t_stop[:, None]], axis=1), axis=1)
    return bp, t_stop, empty


def _first_sign_change(ts: np.ndarray, g: np.ndarray, empty: np.ndarray):
    """The bracket ``[ta, tb]`` of the first sample-level crossing from above, whether
    there is one (``hit``) and the last sample before any change (``limit``)."""
    above = g > 0.0
    change = above[:, :-1] != above[:, 1:]
    has_change = change.any(axis=1)
    first = np.argmax(change, axis=1)
    rows = np.arange(len(ts))
    from_above = has_change & above[rows, first]
    ta = np.where(from_above, ts[rows, first], np.nan)
    tb = np.where(from_above, ts[rows, np.minimum(first + 1, ts.shape[1] - 1)], np.nan)
    hit = from_above & ~empty
    limit = np.where(has_change, first, ts.shape[1] - 1)  # samples 0..limit are all on one side
    return ta, tb, hit, limit


def _hidden_dips(scene, parts, o, d, ts, g, limit, empty, bracket) -> None:
    """Refine every local minimum of positive samples before the first change by
    golden-section search; a negative one moves the ray's bracket ``(ta, tb, hit)``
    (updated in place) to the earliest such dip."""
    ta, tb, hit = bracket
    m = ts.shape[1]
    idx = np.arange(1, m - 1)
    gm, g0, gp = g[:, :-2], g[:, 1:-1], g[:, 2:]
    cand = (
        (g0 <= gm)
        & (g0 <= gp)
        & (ts[:, 2:] > ts[:, :-2])
        & (idx[None, :] + 1 <= limit[:, None])
        & (g[:, [0]] > 0.0)
        & ~empty[:, None]
    )
    ray_i, col = np.nonzero(cand)
    if not len(ray_i):
        return
    k_mid = col + 1
    t_min, g_min = _golden_minimum(
        scene, parts, o[ray_i], d[ray_i], ts[ray_i, k_mid - 1], ts[ray_i, k_mid + 1]
    )
    neg = g_min <= 0.0
    if not neg.any():
        return
    ray_n, k_n, tmin_n = ray_i[neg], k_mid[neg], t_min[neg]
    # keep the earliest dip per ray (nonzero() is row-major: k ascending)
    order = np.lexsort((k_n, ray_n))
    ray_n, k_n, tmin_n = ray_n[order], k_n[order], tmin_n[order]
    first_of_ray = np.ones(len(ray_n), dtype=bool)
    first_of_ray[1:] = ray_n[1:] != ray_n[:-1]
    ray_n, k_n, tmin_n = ray_n[first_of_ray], k_n[first_of_ray], tmin_n[first_of_ray]
    ta[ray_n] = ts[ray_n, k_n - 1]
    tb[ray_n] = tmin_n
    hit[ray_n] = True


def first_hit(scene: Scene, origin, directions):
    """First crossing from above of rays ``origin + t d`` with the surface ``f + D``.

    ``origin``: (3,) or broadcastable to ``directions`` (…, 3), mm. Directions are
    normalised here; ``t`` is the distance in mm along them. Returns
    ``(t, hit_points, normals, valid)`` with shapes (…), (…, 3), (…, 3), (…); NaN where
    ``valid`` is False (no hit, or the first crossing is from below).
    """
    d = np.asarray(directions, dtype=np.float64)
    shape = d.shape[:-1]
    o = np.broadcast_to(np.asarray(origin, dtype=np.float64), d.shape).reshape(-1, 3)
    d = d.reshape(-1, 3)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    n = len(d)
    t = np.full(n, np.nan)
    valid = np.zeros(n, dtype=bool)
    for s in range(0, n, _CHUNK_RAYS):
        t[s : s + _CHUNK_RAYS], valid[s : s + _CHUNK_RAYS] = _first_hit_rays(
            scene, o[s : s + _CHUNK_RAYS], d[s : s + _CHUNK_RAYS]
        )
    points = o + t[:, None] * d
    normals = np.full((n, 3), np.nan)
    if valid.any():
        normals[valid] = _normals(scene, scene.active, points[valid, 0], points[valid, 2])
    return (
        t.reshape(shape),
        points.reshape(shape + (3,)),
        normals.reshape(shape + (3,)),
        valid.reshape(shape),
    )


# ============================================================================ tracing
def _reflect(d: np.ndarray, n: np.ndarray) -> np.ndarray:
    return d - 2.0 * np.einsum("nk,nk->n", d, n)[:, None] * n


@dataclass(frozen=True)
class Rays:
    """A frame's rays traced to the surface and on to the emitter (:func:`trace_rays`),
    ready to be shaded with any pattern the emitter shows (:func:`shade_rays`).

    ``shape``: ``(h, w, S)``, the ``N = h w S`` rays (pixel-major), each from ``origins``
    along unit ``directions`` (N, 3 each). Per ray: ``distance`` from its origin to its
    surface hit (mm, NaN where it hits none), ``u``, ``v`` where its mirror ray meets the
    emitter (mm, NaN where not), ``ok`` whether it does. The hit points and normals are
    not kept: shading computes them again, as the trace did."""

    shape: tuple[int, int, int]
    origins: np.ndarray
    directions: np.ndarray
    distance: np.ndarray
    u: np.ndarray
    v: np.ndarray
    ok: np.ndarray

    @property
    def nbytes(self) -> int:
        """The bytes its arrays hold."""
        arrays = (self.origins, self.directions, self.distance, self.u, self.v, self.ok)
        return sum(array.nbytes for array in arrays)

    def chunks(self, scene: Scene):
        """Per chunk of :data:`_CHUNK_RAYS` rays that hits the surface: the indices of its
        rays that do, their hit points, unit directions and unit normals."""
        parts = scene.active
        for s in range(0, self.ok.size, _CHUNK_RAYS):
            t = self.distance[s : s + _CHUNK_RAYS]
            hit = np.isfinite(t)
            if not hit.any():
                continue
            d = self.directions[s : s + _CHUNK_RAYS][hit]
            p = self.origins[s : s + _CHUNK_RAYS][hit] + t[hit, None] * d
            yield np.nonzero(hit)[0] + s, p, d, _normals(scene, parts, p[:, 0], p[:, 2])


def trace_rays(scene: Scene, rows: slice | None = None, cols: slice | None = None) -> Rays:
    """Trace every ray of ``scene``'s camera (``rows``/``cols``: a window of the full
    sensor; ``render.supersample`` and a lens's samples as :func:`trace`) to its first
    surface hit and its mirror ray to the emitter plane, chunk by chunk."""
    parts = scene.active
    origins, dirs = parts.camera.sample_rays(scene, rows, cols, scene.render.supersample)
    h, w, samples = dirs.shape[:3]
    origins, d = np.ascontiguousarray(origins.reshape(-1, 3)), dirs.reshape(-1, 3)
    n = len(d)
    distance = np.full(n, np.nan)
    for s in range(0, n, _CHUNK_RAYS):
        distance[s : s + _CHUNK_RAYS] = _first_hit_rays(
            scene, origins[s : s + _CHUNK_RAYS], d[s : s + _CHUNK_RAYS]
        )[0]
    u, v, ok = np.full(n, np.nan), np.full(n, np.nan), np.zeros(n, dtype=bool)
    rays = Rays((h, w, samples), origins, d, distance, u, v, ok)
    for idx, p, dh, normals in rays.chunks(scene):
        u[idx], v[idx], ok[idx] = parts.emitter.coordinates(scene, p, _reflect(dh, normals))
    return rays


def shade_rays(scene: Scene, rays: Rays, shown: tuple[Scene, ...]) -> np.ndarray:
    """Each ray's value (len(shown), N) for each scene of ``shown``: ``scene`` itself or
    ``scene`` showing another pattern (an emitter frame, a phase: the same rays, emitter
    plane, reflection model and Fresnel term as ``scene``); 0 where a ray hits no surface.
    Shaded a chunk of :data:`_CHUNK_RAYS` rays at a time."""
    values = np.zeros((len(shown), rays.ok.size))
    if not shown:
        return values
    fresnel = scene.active.fresnel
    for idx, p, d, n in rays.chunks(scene):
        u, v, ok = rays.u[idx], rays.v[idx], rays.ok[idx]
        weight = fresnel.reflectance(scene, -np.einsum("nk,nk->n", d, n))
        uv = np.stack([u, v], axis=-1)
        for k, view in enumerate(shown):
            values[k, idx] = view.active.reflection.shade(view, p, d, n, uv, ok) * weight
    return values


def trace(
    scene: Scene,
    outputs: Iterable[str] | str = ("image", "uv", "mask"),
    *,
    rows: slice | None = None,
    cols: slice | None = None,
    frames: Iterable[Any] = (),
    develop: bool = True,
    rays: Rays | None = None,
) -> Frame:
    """Render ``scene`` in float64: ``image`` (H, W) radiance, ``uv`` (H, W, 2) in mm (NaN
    where no sample reaches the emitter), ``mask`` (H, W) bool; fields not asked for are
    None. ``rows``/``cols`` trace a window of the full sensor (the arrays have the
    window's shape). Supersampling follows :mod:`glshade.frame`; ``render.precision`` is
    ignored (always float64); ``rays`` is every pixel's count of rays, all traced. With
    Blinn-Phong, ``uv``/``mask`` are the mirror ray's.

    ``distance`` (H, W): the distance (mm) from each ray's origin to its surface hit along
    it, the mean over the samples that hit (NaN where none does). ``frames`` (F, H, W),
    with the emitter frames ``frames`` (:meth:`EmitterComponent.sequence`): every ray is
    traced once and shaded for each frame (the scene the emitter's ``showing`` gives),
    radiance as ``image`` would be for that frame alone, never developed. ``develop``:
    the image as the sensor records it (:meth:`Active.develop`, ``camera.exposure`` as
    the sensor reads it) or, when False, the radiance. ``iterations`` is not computed
    (None). ``rays``: this scene's rays traced already (:func:`trace_rays`, of the same
    window), to be shaded only."""
    wanted = normalize_outputs(outputs if isinstance(outputs, str) else tuple(outputs))
    stack = tuple(frames)
    if ("frames" in wanted) != bool(stack):
        raise GlshadeError("trace: the frames output and a non-empty list of frames go together")
    emitter = scene.active.emitter
    shown = ((scene,) if "image" in wanted else ()) + tuple(
        emitter.showing(scene, frame) for frame in stack
    )
    traced = rays if rays is not None else trace_rays(scene, rows, cols)
    h, w, samples = traced.shape
    means = shade_rays(scene, traced, shown).reshape(len(shown), h, w, samples).mean(axis=3)
    ok = traced.ok.reshape(h, w, samples)
    image = uv = mask = distance = None
    if "image" in wanted:
        image = means[0]
        if develop:
            image = scene.active.develop(scene, image)
    if "uv" in wanted:
        uv = _mean_where(np.stack([traced.u, traced.v], axis=-1).reshape(h, w, samples, 2), ok)
    if "mask" in wanted:
        mask = ok.sum(axis=2) > 0
    if "distance" in wanted:
        t = traced.distance.reshape(h, w, samples)
        distance = _mean_where(t[..., None], np.isfinite(t))[..., 0]
    count = np.full((h, w), float(samples), np.float32) if "rays" in wanted else None
    layers = means[len(shown) - len(stack) :] if stack else None
    return Frame(image=image, uv=uv, mask=mask, distance=distance, rays=count, frames=layers)


def _mean_where(values: np.ndarray, where: np.ndarray) -> np.ndarray:
    """The mean of ``values`` (h, w, S, C) over the samples ``where`` (h, w, S) is True;
    NaN where it is True for none."""
    count = where.sum(axis=2)[..., None]
    total = np.where(where[..., None], values, 0.0).sum(axis=2)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / count, np.nan)


__all__ = [
    "Rays",
    "emitter_coordinates",
    "first_hit",
    "pixel_rays",
    "radiance",
    "shade_rays",
    "surface_height",
    "trace",
    "trace_rays",
]
