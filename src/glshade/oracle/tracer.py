"""A NumPy float64 backward ray tracer: the test oracle for the GLSL renderer.

Written from ``SPEC.md`` alone (no shader code was consulted), it traces one ray per
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
from typing import Iterable

import numpy as np

from glshade.errors import SceneError
from glshade.frame import Frame, normalize_outputs
from glshade.scene import Camera, Defect, Emitter, Scene, Surface

#: Uniform samples of the gap per segment between breakpoints.
_SAMPLES_PER_SEGMENT = 64
#: Rays traced at once (bounds the (rays x samples) work arrays).
_CHUNK_RAYS = 2048
#: Margin (mm) added to the band [lo, hi] so that its ends bracket a zero-depth defect.
_BAND_MARGIN_MM = 1e-9
#: Mahalanobis radii of the defect ellipses used as breakpoints.
_DEFECT_RADII = (1.0, 3.0, 8.5)
#: Golden-section iterations for hidden dips (bracket shrinks by 0.618^k).
_GOLDEN_ITERATIONS = 64
#: Blinn-Phong box half-width in lobe standard deviations (of the half vector's angle,
#: 1/sqrt(n)): the weight beyond is below exp(-32).
_LOBE_SPAN_STD = 8.0
#: The box's half-width is capped at this angle (rad) from the normal.
_LOBE_MAX_ANGLE = 1.3
#: Blinn-Phong grid points per lobe standard deviation (midpoint rule on a Gaussian of
#: std s with step s/2 errs by ~2 exp(-8π²) ~ 1e-34 relative).
_LOBE_POINTS_PER_STD = 2.0
#: Blinn-Phong grid points per stripe sigma on the emitter, at the steepest ∂v/∂(a, b)
#: (step σ/1.25, with the slope safety below σ/1.5: aliasing ~2 exp(-2π² 1.5²) ~ 1e-19).
_STRIPE_POINTS_PER_SIGMA = 1.25
#: Margin on the slope of v measured on a 9 x 9 coarse grid of the box.
_SLOPE_SAFETY = 1.2
#: Minimum grid points per axis of the Blinn-Phong quadrature.
_LOBE_MIN_POINTS = 48
#: Most grid points per axis (beyond it the call is refused rather than under-resolved).
_LOBE_MAX_POINTS = 8192
#: Work-array budget (grid points x pixels) of one Blinn-Phong batch.
_LOBE_BATCH = 1_000_000
#: The smallest Blinn-Phong exponent whose lobe (8 std) fits the gnomonic box.
MIN_SHININESS = 50.0


# ============================================================================ camera
def pixel_rays(
    camera: Camera,
    rows: slice | None = None,
    cols: slice | None = None,
    supersample: int = 1,
) -> tuple[np.ndarray, np.ndarray]:
    """Camera rays of SPEC §2: ``(origin, directions)``, float64.

    ``origin`` is the principal point ``C`` (3,) in mm. ``directions`` are unit vectors;
    their shape is ``(h, w, 3)`` for ``supersample == 1`` and ``(h, w, n, n, 3)`` for
    ``n = supersample > 1``, where ``[..., a, b, :]`` is the sub-pixel sample at
    ``((b + 0.5)/n, (a + 0.5)/n)`` inside the pixel (``b`` along the row, ``a`` down the
    column). ``rows``/``cols`` select pixels of the full sensor (row 0 at the top).
    """
    n = int(supersample)
    if n < 1:
        raise ValueError(f"supersample: must be >= 1, got {supersample!r}")
    i = np.arange(camera.height, dtype=np.float64)[rows if rows is not None else slice(None)]
    j = np.arange(camera.width, dtype=np.float64)[cols if cols is not None else slice(None)]
    offset = (np.arange(n, dtype=np.float64) + 0.5) / n
    pitch = camera.pixel_pitch
    # sensor coordinates (mm), indexed (i, j, a, b)
    sx = (j[None, :, None, None] + offset[None, None, None, :] - camera.width / 2.0) * pitch
    sy = (camera.height / 2.0 - i[:, None, None, None] - offset[None, None, :, None]) * pitch
    forward, right, up = camera.basis()
    d = camera.focal * forward + sx[..., None] * right + sy[..., None] * up
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    if n == 1:
        d = d[:, :, 0, 0, :]
    return camera.position(), d


# ============================================================================ surface
def _radius(surface: Surface) -> tuple[float, float]:
    """``(s, a)``: ``s = sign(R)`` (+1 convex, -1 concave), ``a = |R|`` (mm)."""
    return (1.0 if surface.radius > 0 else -1.0), abs(surface.radius)


def _rho(surface: Surface, x: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Distance (mm) from the surface's axis in the ``xz`` plane: the sqrt's argument is
    ``R² - rho²``."""
    if surface.kind == "sphere":
        return np.hypot(x, z)
    if surface.axis == "z":
        return np.abs(x)
    return np.abs(z)


def _sag(surface: Surface, x: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Base height ``f`` (mm) and ``w = sqrt(R² - rho²)`` with ``rho`` clipped to ``|R|``.

    ``f = -s rho² / (a + w)`` equals ``s (w - a)`` without its cancellation near the
    apex; ``w = sqrt((a - rho)(a + rho))`` keeps its digits near the rim.
    """
    s, a = _radius(surface)
    rho = np.minimum(_rho(surface, x, z), a)
    w = np.sqrt((a - rho) * (a + rho))
    return -s * rho * rho / (a + w), w


def _defect(defect: Defect, x: np.ndarray, z: np.ndarray) -> np.ndarray:
    """``D = -dmax exp(-1/2 p^T Σ^-1 p)`` (mm), ``p = (x - x0, z - z0)``."""
    if not defect.present:
        return np.zeros(np.broadcast(x, z).shape)
    ia, ib, ic = defect.inverse_covariance()
    px = x - defect.x0
    pz = z - defect.z0
    q = ia * px * px + 2.0 * ib * px * pz + ic * pz * pz
    return -defect.dmax * np.exp(-0.5 * q)


def _defect_gradient(defect: Defect, x: np.ndarray, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(D_x, D_z)`` (dimensionless): ``∇D = -D Σ^-1 p``."""
    if not defect.present:
        zero = np.zeros(np.broadcast(x, z).shape)
        return zero, zero
    ia, ib, ic = defect.inverse_covariance()
    px = x - defect.x0
    pz = z - defect.z0
    d = _defect(defect, x, z)
    return -d * (ia * px + ib * pz), -d * (ib * px + ic * pz)


def surface_height(surface: Surface, defect: Defect, x, z) -> np.ndarray:
    """Height ``y = f(x, z) + D(x, z)`` (mm) of the surface at ``(x, z)`` (mm); NaN where
    the base surface does not exist (``R² - rho² < 0``)."""
    x = np.asarray(x, dtype=np.float64)
    z = np.asarray(z, dtype=np.float64)
    d = _defect(defect, x, z)
    if surface.kind == "flat":
        return d
    f, _ = _sag(surface, x, z)
    outside = _rho(surface, x, z) > abs(surface.radius)
    return np.where(outside, np.nan, f + d)


def _gap(surface: Surface, defect: Defect, o: np.ndarray, d: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``g(t) = y - f - D`` (mm) along rays ``o + t d``; ``o, d`` (N, 3), ``t`` (N,) or
    (N, M). ``rho`` is clipped to the domain (samples there are inside up to roundoff)."""
    ex = (slice(None),) + (None,) * (t.ndim - 1)
    x = o[:, 0][ex] + t * d[:, 0][ex]
    y = o[:, 1][ex] + t * d[:, 1][ex]
    z = o[:, 2][ex] + t * d[:, 2][ex]
    g = y - _defect(defect, x, z)
    if surface.kind != "flat":
        g = g - _sag(surface, x, z)[0]
    return g


def _normals(surface: Surface, defect: Defect, x: np.ndarray, z: np.ndarray) -> np.ndarray:
    """Unit normals (…, 3) of ``h = f + D``: ``(-h_x, 1, -h_z)`` times ``w`` for curved
    kinds, i.e. ``(s x - w D_x, w, s z - w D_z)`` for a sphere (finite at ``w = 0``)."""
    dx, dz = _defect_gradient(defect, x, z)
    if surface.kind == "flat":
        n = np.stack([-dx, np.ones_like(dx), -dz], axis=-1)
    else:
        s, _ = _radius(surface)
        _, w = _sag(surface, x, z)
        if surface.kind == "sphere":
            n = np.stack([s * x - w * dx, w, s * z - w * dz], axis=-1)
        elif surface.axis == "z":
            n = np.stack([s * x - w * dx, w, -w * dz], axis=-1)
        else:
            n = np.stack([-w * dx, w, s * z - w * dz], axis=-1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


# ============================================================================ roots
def _stable_roots(qa: np.ndarray, qb: np.ndarray, qc: np.ndarray, sqrt_disc: np.ndarray):
    """Roots ``t1 <= t2`` of ``qa t² + 2 qb t + qc = 0`` given ``sqrt(qb² - qa qc)``
    (NaN where negative/NaN or ``qa == 0``), without cancellation:
    ``q = -(qb + sign(qb) sqrt_disc)``, ``t = q / qa`` and ``qc / q``."""
    with np.errstate(divide="ignore", invalid="ignore"):
        q = -(qb + np.copysign(sqrt_disc, qb))
        t1 = q / qa
        t2 = np.where(q == 0.0, 0.0, qc / q)
        bad = ~np.isfinite(sqrt_disc) | (qa == 0.0)
        t1 = np.where(bad, np.nan, t1)
        t2 = np.where(bad, np.nan, t2)
    return np.minimum(t1, t2), np.maximum(t1, t2)


def _circle_roots(oc: np.ndarray, dv: np.ndarray, radius: float):
    """Ray ``oc + t dv`` against the sphere/circle ``|p| = radius`` in ``k`` dims
    (``oc, dv``: (N, k)). The discriminant is ``qa (r² - |perp|²)`` with ``perp`` the
    closest-approach vector, computed as ``(r - |perp|)(r + |perp|)``: no cancellation
    between ``qb²`` and ``qa qc`` for rays passing close to the centre or far away."""
    qa = np.einsum("nk,nk->n", dv, dv)
    qb = np.einsum("nk,nk->n", oc, dv)
    qc = np.einsum("nk,nk->n", oc, oc) - radius * radius
    with np.errstate(divide="ignore", invalid="ignore"):
        tc = -qb / qa
        perp = np.linalg.norm(oc + tc[:, None] * dv, axis=1)
        inner = (radius - perp) * (radius + perp)
        sqrt_disc = np.where(inner >= 0.0, np.sqrt(qa * np.maximum(inner, 0.0)), np.nan)
    return _stable_roots(qa, qb, qc, sqrt_disc)


def _domain_interval(surface: Surface, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``[t_in, t_out]`` (mm) where the ray is over the surface's domain; ``±inf`` when
    unbounded, NaN when empty."""
    n = len(d)
    if surface.kind == "flat":
        return np.full(n, -np.inf), np.full(n, np.inf)
    _, a = _radius(surface)
    if surface.kind == "sphere":
        dv = d[:, [0, 2]]
        t1, t2 = _circle_roots(o[:, [0, 2]], dv, a)
        vertical = np.einsum("nk,nk->n", dv, dv) == 0.0
        inside = np.hypot(o[:, 0], o[:, 2]) <= a
    else:
        k = 0 if surface.axis == "z" else 2
        oc, dc = o[:, k], d[:, k]
        with np.errstate(divide="ignore", invalid="ignore"):
            ta, tb = (-a - oc) / dc, (a - oc) / dc
        t1, t2 = np.minimum(ta, tb), np.maximum(ta, tb)
        vertical = dc == 0.0
        inside = np.abs(oc) <= a
    t1 = np.where(vertical, np.where(inside, -np.inf, np.nan), t1)
    t2 = np.where(vertical, np.where(inside, np.inf, np.nan), t2)
    return t1, t2


def _band_roots(surface: Surface, o: np.ndarray, d: np.ndarray, shift: float) -> list[np.ndarray]:
    """Ray parameters where ``y - f = shift`` (mm) on the full base quadric (spurious
    roots on the other hemisphere are harmless: they only add breakpoints)."""
    if surface.kind == "flat":
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (shift - o[:, 1]) / d[:, 1]
        return [np.where(np.isfinite(t), t, np.nan)]
    s, a = _radius(surface)
    y_centre = shift - s * a  # centre of the shifted sphere / circle
    oc = o - np.array([0.0, y_centre, 0.0])
    if surface.kind == "sphere":
        dims = [0, 1, 2]
    elif surface.axis == "z":
        dims = [0, 1]
    else:
        dims = [2, 1]
    return list(_circle_roots(oc[:, dims], d[:, dims], a))


def _ellipse_roots(defect: Defect, o: np.ndarray, d: np.ndarray, radius: float) -> list[np.ndarray]:
    """Ray parameters where the Mahalanobis distance to the defect centre is ``radius``."""
    ia, ib, ic = defect.inverse_covariance()
    px, pz = o[:, 0] - defect.x0, o[:, 2] - defect.z0
    dx, dz = d[:, 0], d[:, 2]
    qa = ia * dx * dx + 2.0 * ib * dx * dz + ic * dz * dz
    qb = ia * px * dx + ib * (px * dz + pz * dx) + ic * pz * dz
    qc = ia * px * px + 2.0 * ib * px * pz + ic * pz * pz - radius * radius
    disc = qb * qb - qa * qc
    sqrt_disc = np.where(disc >= 0.0, np.sqrt(np.maximum(disc, 0.0)), np.nan)
    return list(_stable_roots(qa, qb, qc, sqrt_disc))


# ============================================================================ solvers
def _bisect(surface, defect, o, d, ta, tb):
    """Shrink ``[ta, tb]`` with ``g(ta) > 0 >= g(tb)`` to adjacent floats; returns its
    midpoint (mm)."""
    ta = ta.copy()
    tb = tb.copy()
    for _ in range(2200):  # a hard bound; ~60 iterations reach one ulp
        tm = 0.5 * (ta + tb)
        live = (tm > ta) & (tm < tb)
        if not live.any():
            break
        pos = _gap(surface, defect, o, d, tm) > 0.0
        ta = np.where(live & pos, tm, ta)
        tb = np.where(live & ~pos, tm, tb)
    return ta + 0.5 * (tb - ta)


def _golden_minimum(surface, defect, o, d, a, b):
    """Golden-section search for the minimum of ``g`` on ``[a, b]`` (per ray); returns
    ``(t_min, g_min)``, stopping early for rays where a negative value is found."""
    phi = (math.sqrt(5.0) - 1.0) / 2.0
    c = b - phi * (b - a)
    e = a + phi * (b - a)
    gc = _gap(surface, defect, o, d, c)
    ge = _gap(surface, defect, o, d, e)
    best_t = np.where(gc < ge, c, e)
    best_g = np.minimum(gc, ge)
    for _ in range(_GOLDEN_ITERATIONS):
        if (best_g < 0.0).all():
            break
        left = gc < ge  # the minimum lies in [a, e]
        b = np.where(left, e, b)
        a = np.where(left, a, c)
        new = np.where(left, b - phi * (b - a), a + phi * (b - a))
        gn = _gap(surface, defect, o, d, new)
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
    surface, defect = scene.surface, scene.defect
    n = len(d)
    t_in, t_out = _domain_interval(surface, o, d)
    t_start = np.maximum(t_in, 0.0)
    empty = ~(t_out >= t_start)  # also NaN (no domain)

    lo, hi = min(0.0, -defect.dmax), max(0.0, -defect.dmax)
    roots = _band_roots(surface, o, d, hi + _BAND_MARGIN_MM) + _band_roots(surface, o, d, lo - _BAND_MARGIN_MM)
    if defect.present:
        for radius in _DEFECT_RADII:
            roots += _ellipse_roots(defect, o, d, radius)
    bp = np.stack(roots, axis=1)
    finite = np.isfinite(bp)
    last_root = np.max(np.where(finite, bp, -np.inf), axis=1)
    t_stop = np.where(np.isfinite(t_out), t_out, last_root)
    t_stop = np.where(empty, t_start, np.maximum(t_stop, t_start))
    t_start = np.where(empty, 0.0, t_start)
    t_stop = np.where(empty, 0.0, t_stop)
    bp = np.clip(np.where(finite, bp, t_stop[:, None]), t_start[:, None], t_stop[:, None])
    bp = np.sort(np.concatenate([t_start[:, None], bp, t_stop[:, None]], axis=1), axis=1)

    k = _SAMPLES_PER_SEGMENT
    frac = np.arange(k, dtype=np.float64) / k
    seg_lo, seg_hi = bp[:, :-1], bp[:, 1:]
    ts = (seg_lo[:, :, None] + (seg_hi - seg_lo)[:, :, None] * frac).reshape(n, -1)
    ts = np.concatenate([ts, t_stop[:, None]], axis=1)
    g = _gap(surface, defect, o, d, ts)
    above = g > 0.0

    change = above[:, :-1] != above[:, 1:]
    has_change = change.any(axis=1)
    first = np.argmax(change, axis=1)
    rows = np.arange(n)
    from_above = has_change & above[rows, first]
    # bracket of the first sample-level crossing from above
    ta = np.where(from_above, ts[rows, first], np.nan)
    tb = np.where(from_above, ts[rows, np.minimum(first + 1, ts.shape[1] - 1)], np.nan)
    hit = from_above & ~empty

    # hidden dips: local minima of positive samples before the first change
    m = ts.shape[1]
    limit = np.where(has_change, first, m - 1)  # samples 0..limit are all on one side
    idx = np.arange(1, m - 1)
    gm, g0, gp = g[:, :-2], g[:, 1:-1], g[:, 2:]
    cand = (
        (g0 <= gm)
        & (g0 <= gp)
        & (ts[:, 2:] > ts[:, :-2])
        & (idx[None, :] + 1 <= limit[:, None])
        & above[:, [0]]
        & ~empty[:, None]
    )
    ray_i, col = np.nonzero(cand)
    if len(ray_i):
        k_mid = col + 1
        t_min, g_min = _golden_minimum(
            surface, defect, o[ray_i], d[ray_i], ts[ray_i, k_mid - 1], ts[ray_i, k_mid + 1]
        )
        neg = g_min <= 0.0
        if neg.any():
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

    t = np.full(n, np.nan)
    if hit.any():
        t[hit] = _bisect(surface, defect, o[hit], d[hit], ta[hit], tb[hit])
    return t, hit


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
        normals[valid] = _normals(scene.surface, scene.defect, points[valid, 0], points[valid, 2])
    return t.reshape(shape), points.reshape(shape + (3,)), normals.reshape(shape + (3,)), valid.reshape(shape)


# ============================================================================ emitter
def emitter_coordinates(scene: Scene, points, directions):
    """Where rays ``points + t r`` (mm; ``r`` need not be unit) meet the emitter.

    Returns ``(u, v, valid)``: screen coordinates in mm, shape (…); ``valid`` requires
    ``r·n_E < 0`` (towards the front), ``t_e > 0`` and ``|u|, |v| <= half_size``.
    ``u, v`` are NaN where not valid.
    """
    frame = scene.emitter_frame()
    p = np.asarray(points, dtype=np.float64)
    r = np.asarray(directions, dtype=np.float64)
    denom = r @ frame.normal
    rel = p - frame.centre
    with np.errstate(divide="ignore", invalid="ignore"):
        t_e = -(rel @ frame.normal) / denom
        q = rel + t_e[..., None] * r
    u = q @ frame.e_u
    v = q @ frame.e_v
    hu, hv = scene.emitter.half_size
    valid = (denom < 0.0) & (t_e > 0.0) & (np.abs(u) <= hu) & (np.abs(v) <= hv)
    return np.where(valid, u, np.nan), np.where(valid, v, np.nan), valid


def radiance(emitter: Emitter, v) -> np.ndarray:
    """Stripe radiance ``L(v) = Σ_k exp(-(v - phase - k period)² / (2 σ²))`` at ``v`` (mm).

    Every stripe within ``10σ`` of ``v`` is summed (at most one more, beyond, adds
    < exp(-50)).
    When more than 64 stripes would overlap (``σ > 3.1 period``) the identical Poisson
    form ``(σ sqrt(2π)/period) (1 + 2 Σ_m exp(-2π² σ² m²/period²) cos(2π m x/period))`` is
    used instead. NaN propagates.
    """
    v = np.asarray(v, dtype=np.float64)
    sigma = emitter.sigma_mm
    period = emitter.period
    x = v - emitter.phase
    span = 10.0 * sigma
    terms = int(math.floor(2.0 * span / period)) + 1  # stripes k with |x - k period| <= span
    if terms <= 64:
        with np.errstate(invalid="ignore"):
            k0 = np.ceil((x - span) / period)
        out = np.zeros_like(x)
        for j in range(terms):
            r = x - (k0 + j) * period
            out += np.exp(-(r * r) / (2.0 * sigma * sigma))
        return out
    ratio = sigma / period
    m_max = int(math.ceil(math.sqrt(45.0 / (2.0 * math.pi**2)) / ratio)) + 1  # exp(-45) ~ 3e-20
    phase = 2.0 * math.pi * x / period
    series = np.ones_like(x)
    for m in range(1, m_max + 1):
        series += 2.0 * math.exp(-2.0 * math.pi**2 * ratio**2 * m * m) * np.cos(m * phase)
    return ratio * math.sqrt(2.0 * math.pi) * series


def _reflect(d: np.ndarray, n: np.ndarray) -> np.ndarray:
    return d - 2.0 * np.einsum("nk,nk->n", d, n)[:, None] * n


# ============================================================================ Blinn-Phong
def _lobe_basis(n_s: np.ndarray, wo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Tangent basis of the normal: ``e1`` towards ``wo`` (in the plane of incidence, the
    direction in which ``v`` mostly changes), ``e2 = n × e1`` across."""
    e1 = wo - np.einsum("nk,nk->n", wo, n_s)[:, None] * n_s
    norm = np.linalg.norm(e1, axis=1)
    degenerate = norm < 1e-12  # normal incidence: any perpendicular of n
    if degenerate.any():
        helper = np.where(np.abs(n_s[:, [0]]) < 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
        e1 = np.where(degenerate[:, None], np.cross(n_s, helper), e1)
        norm = np.linalg.norm(e1, axis=1)
    e1 = e1 / norm[:, None]
    return e1, np.cross(n_s, e1)


def _lobe_samples(scene, p, wo, n_s, e1, e2, a, b):
    """Weights ``∝ w dω_l`` and the emitter's ``v`` (mm) and validity at the gnomonic
    half-vector offsets ``(a, b)`` (grid arrays (1, n1, n2)) for the N pixels of ``p``.

    ``h = (n + a e1 + b e2)/sqrt(1 + a² + b²)`` (unit: the basis is orthonormal), so
    ``n·h = (1 + a² + b²)^{-1/2}``, ``dω_h = da db (1 + a² + b²)^{-3/2}`` and the weight
    ``(n·h)^n 4 (wo·h) dω_h / (da db)`` is ``(1 + a² + b²)^{-(n+3)/2} 4 max(wo·h, 0)``. The
    direction ``l = 2 (wo·h) h - wo`` is needed only through its dot products with the
    emitter's axes, which are linear in ``(a, b)``: no 3-vectors per sample.
    """
    frame = scene.emitter_frame()
    shininess = scene.render.shininess
    rr = 1.0 + a * a + b * b
    inv = 1.0 / np.sqrt(rr)
    base = np.exp(-0.5 * (shininess + 3.0) * np.log(rr))

    def along(x: np.ndarray):
        """``(h·x, wo·x)`` for a fixed vector ``x``, per pixel and sample."""
        hx = ((n_s @ x)[:, None, None] + a * (e1 @ x)[:, None, None] + b * (e2 @ x)[:, None, None]) * inv
        return hx, (wo @ x)[:, None, None]

    wo_h = (
        np.einsum("nk,nk->n", wo, n_s)[:, None, None]
        + a * np.einsum("nk,nk->n", wo, e1)[:, None, None]
        + b * np.einsum("nk,nk->n", wo, e2)[:, None, None]
    ) * inv
    weight = base * 4.0 * np.maximum(wo_h, 0.0)
    h_n, wo_n = along(frame.normal)
    h_v, wo_v = along(frame.e_v)
    h_u, wo_u = along(frame.e_u)
    l_n = 2.0 * wo_h * h_n - wo_n  # l·n_E
    rel = p - frame.centre
    with np.errstate(divide="ignore", invalid="ignore"):
        t_e = -(rel @ frame.normal)[:, None, None] / l_n
        v = (rel @ frame.e_v)[:, None, None] + t_e * (2.0 * wo_h * h_v - wo_v)
        u = (rel @ frame.e_u)[:, None, None] + t_e * (2.0 * wo_h * h_u - wo_u)
    hu, hv = scene.emitter.half_size
    ok = (l_n < 0.0) & (t_e > 0.0) & (np.abs(u) <= hu) & (np.abs(v) <= hv) & (wo_h > 0.0)
    return weight, v, ok


def _grid_points(scene, p, wo, n_s, e1, e2, half) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel grid sizes ``(N1, N2)`` along ``(e1, e2)`` that resolve the lobe and the
    stripes, rounded up to multiples of 16 (pixels with equal sizes share a batch).
    ``v`` is sampled on a 9 x 9 coarse grid of each box to bound its slopes."""
    step_lobe = 1.0 / (math.sqrt(scene.render.shininess) * _LOBE_POINTS_PER_STD)
    n_lobe = 2.0 * half / step_lobe
    c = np.linspace(-1.0, 1.0, 9) * half
    a, b = np.meshgrid(c, c, indexing="ij")
    _, v, ok = _lobe_samples(scene, p, wo, n_s, e1, e2, a[None], b[None])
    step = 2.0 * half / 8.0
    with np.errstate(invalid="ignore"):
        dv1 = np.where(ok[:, 1:, :] & ok[:, :-1, :], np.abs(np.diff(v, axis=1)), 0.0) / step
        dv2 = np.where(ok[:, :, 1:] & ok[:, :, :-1], np.abs(np.diff(v, axis=2)), 0.0) / step
    h_v = scene.emitter.sigma_mm / _STRIPE_POINTS_PER_SIGMA
    sizes = []
    for slope in (dv1.max(axis=(1, 2)), dv2.max(axis=(1, 2))):
        wanted = np.maximum(max(_LOBE_MIN_POINTS, n_lobe), _SLOPE_SAFETY * slope * 2.0 * half / h_v)
        if wanted.max() > _LOBE_MAX_POINTS:
            raise SceneError(
                "render.shininess",
                f"large enough for the NumPy reference's Blinn-Phong grid ({wanted.max():.0f} points per "
                f"axis needed to resolve stripes of sigma {scene.emitter.sigma_mm:g} mm; limit {_LOBE_MAX_POINTS})",
                scene.render.shininess,
            )
        sizes.append((16 * np.ceil(wanted / 16.0)).astype(np.int64))
    return sizes[0], sizes[1]


def _blinn_phong(scene: Scene, p: np.ndarray, d: np.ndarray, n_s: np.ndarray) -> np.ndarray:
    """Blinn-Phong pixel values at hit points ``p`` (N, 3) for unit camera directions ``d``
    and normals ``n_s``: brute-force midpoint quadrature of ``∫ L w dω_l / ∫ w dω_l`` over
    the half vector (see the module docstring)."""
    shininess = scene.render.shininess
    if shininess < MIN_SHININESS:
        raise SceneError(
            "render.shininess", f">= {MIN_SHININESS:g} for the NumPy reference's Blinn-Phong quadrature", shininess
        )
    out = np.zeros(len(p))
    if not len(p):
        return out
    wo = -d
    e1, e2 = _lobe_basis(n_s, wo)
    half = math.tan(min(_LOBE_SPAN_STD / math.sqrt(shininess), _LOBE_MAX_ANGLE))
    sizes1, sizes2 = _grid_points(scene, p, wo, n_s, e1, e2, half)
    for n1, n2 in sorted(set(zip(sizes1.tolist(), sizes2.tolist()))):
        group = np.nonzero((sizes1 == n1) & (sizes2 == n2))[0]
        a = (-1.0 + (2.0 * np.arange(n1) + 1.0) / n1) * half  # midpoints of [-half, half]
        b = (-1.0 + (2.0 * np.arange(n2) + 1.0) / n2) * half
        a, b = np.meshgrid(a, b, indexing="ij")
        batch = max(1, _LOBE_BATCH // (n1 * n2))
        for s in range(0, len(group), batch):
            idx = group[s : s + batch]
            weight, v, ok = _lobe_samples(scene, p[idx], wo[idx], n_s[idx], e1[idx], e2[idx], a[None], b[None])
            lum = np.where(ok, radiance(scene.emitter, np.where(ok, v, 0.0)), 0.0)
            out[idx] = np.sum(lum * weight, axis=(1, 2)) / np.sum(weight, axis=(1, 2))
    return out


# ============================================================================ tracing
def _shade(scene: Scene, origin: np.ndarray, d: np.ndarray, want_image: bool):
    """Per-ray ``(value, u, v, reaches_emitter)`` for unit directions ``d`` (N, 3)."""
    n = len(d)
    value = np.zeros(n)
    u = np.full(n, np.nan)
    v = np.full(n, np.nan)
    ok = np.zeros(n, dtype=bool)
    o = np.broadcast_to(origin, (min(n, _CHUNK_RAYS), 3))
    for s in range(0, n, _CHUNK_RAYS):
        dd = d[s : s + _CHUNK_RAYS]
        oo = o[: len(dd)]
        t, hit = _first_hit_rays(scene, oo, dd)
        if not hit.any():
            continue
        idx = np.nonzero(hit)[0] + s
        dh = dd[hit]
        p = oo[hit] + t[hit, None] * dh
        n_s = _normals(scene.surface, scene.defect, p[:, 0], p[:, 2])
        r = _reflect(dh, n_s)
        uu, vv, okk = emitter_coordinates(scene, p, r)
        u[idx], v[idx], ok[idx] = uu, vv, okk
        if want_image:
            if scene.render.reflection == "blinn-phong":
                value[idx] = _blinn_phong(scene, p, dh, n_s)
            else:
                value[idx] = np.where(okk, radiance(scene.emitter, np.where(okk, vv, 0.0)), 0.0)
    return value, u, v, ok


def trace(
    scene: Scene,
    outputs: Iterable[str] | str = ("image", "uv", "mask"),
    *,
    rows: slice | None = None,
    cols: slice | None = None,
) -> Frame:
    """Render ``scene`` in float64: ``image`` (H, W) radiance, ``uv`` (H, W, 2) in mm (NaN
    where no sample reaches the emitter), ``mask`` (H, W) bool; fields not asked for are
    None. ``rows``/``cols`` trace a window of the full sensor (the arrays have the
    window's shape). Supersampling follows :mod:`glshade.frame`; ``render.precision`` is
    ignored (always float64). With Blinn-Phong, ``uv``/``mask`` are the mirror ray's."""
    wanted = normalize_outputs(outputs if isinstance(outputs, str) else tuple(outputs))
    n = scene.render.supersample
    origin, dirs = pixel_rays(scene.camera, rows, cols, n)
    h, w = dirs.shape[:2]
    flat = dirs.reshape(-1, 3)
    value, u, v, ok = _shade(scene, origin, flat, "image" in wanted)
    samples = n * n
    value = value.reshape(h, w, samples)
    ok = ok.reshape(h, w, samples)
    count = ok.sum(axis=2)
    image = uv = mask = None
    if "image" in wanted:
        image = value.mean(axis=2)
    if "uv" in wanted:
        uv_s = np.stack([u, v], axis=-1).reshape(h, w, samples, 2)
        total = np.where(ok[..., None], uv_s, 0.0).sum(axis=2)
        with np.errstate(invalid="ignore", divide="ignore"):
            uv = np.where(count[..., None] > 0, total / count[..., None], np.nan)
    if "mask" in wanted:
        mask = count > 0
    return Frame(image=image, uv=uv, mask=mask)


__all__ = [
    "MIN_SHININESS",
    "emitter_coordinates",
    "first_hit",
    "pixel_rays",
    "radiance",
    "surface_height",
    "trace",
]
