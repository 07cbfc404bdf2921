"""The float64 reference tracer against analytic oracles (no GPU needed).

Each test derives its expected values independently of ``glshade.oracle.tracer``: mirror
images for the flat mirror, sphere/cylinder normals from their centres, the small-slope
closed form of SPEC §6, central differences of the height, a Blinn-Phong quadrature over
the light direction (the tracer integrates over the half vector), a finer camera for
supersampling. Images are small (windows of bigger sensors) so the file runs in seconds.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from glshade.errors import SceneError
from glshade.frame import Frame
from glshade.oracle import tracer as ref
from glshade.scene import (
    Camera,
    Defect,
    Emitter,
    RenderSettings,
    Scene,
    Surface,
    paper_scene,
)


# --------------------------------------------------------------------------- helpers
def _plane_hit(scene: Scene, p: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Independent ray/emitter-plane intersection (SPEC §3): ``(u, v)`` of ``p + s r``."""
    th = math.radians(scene.camera.theta_deg)
    e = scene.emitter.distance * np.array([0.0, math.sin(th), -math.cos(th)])
    n_e = -e / np.linalg.norm(e)
    s = ((e - p) @ n_e) / (direction @ n_e)
    q = p + s[..., None] * direction
    e_v = np.array([0.0, math.cos(th), math.sin(th)])
    return np.stack([(q - e)[..., 0], (q - e) @ e_v], axis=-1)


def _spec_directions(camera: Camera) -> np.ndarray:
    """Pixel directions written straight from SPEC §2 (unit, (H, W, 3))."""
    th = math.radians(camera.theta_deg)
    fwd = -np.array([0.0, math.sin(th), math.cos(th)])
    up = np.array([0.0, math.cos(th), -math.sin(th)])
    right = np.array([1.0, 0.0, 0.0])
    i, j = np.meshgrid(np.arange(camera.height), np.arange(camera.width), indexing="ij")
    sx = (j + 0.5 - camera.width / 2) * camera.pixel_pitch
    sy = (camera.height / 2 - i - 0.5) * camera.pixel_pitch
    d = camera.focal * fwd + sx[..., None] * right + sy[..., None] * up
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def _gap_along(scene: Scene, origin, direction, t) -> np.ndarray:
    """``y - (f + D)`` at ``origin + t direction`` via the public height function."""
    p = origin + np.asarray(t)[..., None] * direction
    return p[..., 1] - ref.surface_height(scene.surface, scene.defect, p[..., 0], p[..., 2])


# --------------------------------------------------------------------------- radiance
def test_radiance_peaks_and_width():
    em = Emitter(period=2.0, phase=0.3)
    sigma = em.sigma_mm
    peaks = 0.3 + 2.0 * np.arange(-5, 6)
    # each peak is 1 plus the neighbours' tails (about 3e-5 at the default width)
    tail = 2 * sum(math.exp(-((k * 2.0) ** 2) / (2 * sigma**2)) for k in range(1, 4))
    np.testing.assert_allclose(ref.radiance(em, peaks), 1.0 + tail, rtol=0, atol=1e-15)
    assert 2e-5 < tail < 5e-5
    # one sigma away from a peak: exp(-1/2) plus the two neighbours
    at_sigma = ref.radiance(em, 0.3 + sigma)
    neighbours = math.exp(-((2.0 - sigma) ** 2) / (2 * sigma**2)) + math.exp(
        -((2.0 + sigma) ** 2) / (2 * sigma**2)
    )
    assert at_sigma == pytest.approx(math.exp(-0.5) + neighbours, abs=1e-15)
    # periodic, and a maximum at the peak
    v = np.linspace(-3, 3, 101)
    np.testing.assert_allclose(ref.radiance(em, v + 2.0), ref.radiance(em, v), atol=1e-13)
    assert ref.radiance(em, v).max() <= ref.radiance(em, 0.3) + 1e-15


@pytest.mark.parametrize("sigma", [0.5, 3.0, 7.0, 40.0])
def test_radiance_wide_stripes_sum_every_overlapping_stripe(sigma):
    """Wide stripes (many overlapping, Poisson branch above ~3 periods) equal the brute
    sum over hundreds of stripes."""
    em = Emitter(period=2.0, stripe_sigma=sigma, phase=0.7)
    v = np.linspace(-9.0, 9.0, 37)
    k = np.arange(-2000, 2001)
    brute = np.exp(-((v[:, None] - 0.7 - 2.0 * k[None, :]) ** 2) / (2 * sigma**2)).sum(axis=1)
    np.testing.assert_allclose(ref.radiance(em, v), brute, rtol=1e-12)


# --------------------------------------------------------------------------- camera
def test_pixel_rays_follow_spec_and_windows():
    cam = Camera(theta_deg=30.0, width=7, height=5, pixel_pitch=0.01)
    origin, d = ref.pixel_rays(cam)
    np.testing.assert_allclose(
        origin, cam.distance * np.array([0.0, 0.5, math.cos(math.radians(30))]), atol=1e-12
    )
    np.testing.assert_allclose(d, _spec_directions(cam), atol=1e-15)
    assert d[0, 3, 1] > d[-1, 3, 1]  # row 0 looks higher (top of the image)
    assert d[2, -1, 0] > 0  # the last column looks towards +x
    _, dw = ref.pixel_rays(cam, rows=slice(1, 4), cols=slice(2, 7, 2))
    np.testing.assert_array_equal(dw, d[1:4, 2:7:2])
    # sub-pixel layout: sample (a, b) of pixel (i, j) is pixel (n i + a, n j + b) of a camera
    # with n times the resolution and 1/n the pitch
    _, ds = ref.pixel_rays(cam, supersample=3)
    assert ds.shape == (5, 7, 3, 3, 3)
    _, fine = ref.pixel_rays(replace(cam, width=21, height=15, pixel_pitch=0.01 / 3))
    np.testing.assert_allclose(ds.transpose(0, 2, 1, 3, 4).reshape(15, 21, 3), fine, atol=1e-15)


def test_surface_height_forms_and_domain():
    x = np.array([0.0, 1e-4, 30.0, 69.999999, 70.0, 70.5])
    z = np.zeros_like(x)
    none = Defect(dmax=0.0)
    sphere = ref.surface_height(Surface("sphere", 70.0), none, x, z)
    np.testing.assert_allclose(
        sphere[:5], np.sqrt(70.0**2 - x[:5] ** 2) - 70.0, rtol=1e-12, atol=1e-13
    )
    assert sphere[1] == pytest.approx(-(1e-4**2) / 140.0, rel=1e-9)  # the sag form keeps digits
    assert np.isnan(sphere[5])
    bowl = ref.surface_height(Surface("sphere", -70.0), none, x, z)
    np.testing.assert_allclose(bowl[:5], -sphere[:5], atol=0)
    cyl_x = ref.surface_height(Surface("cylinder", 70.0, "x"), none, x, np.full_like(x, 80.0))
    assert np.isnan(cyl_x).all()  # |z| > R: no surface, whatever x
    cyl_z = ref.surface_height(Surface("cylinder", 70.0, "z"), none, z, x)
    np.testing.assert_allclose(cyl_z, 0.0)  # axis z: f depends on x only
    dent = Defect(dmax=0.005, sigma_x2=2.0, sigma_z2=1.0, sigma_xz=0.5, x0=0.3, z0=-0.2)
    px, pz = 1.0 - 0.3, -1.0 + 0.2
    inv = np.linalg.inv(np.array([[2.0, 0.5], [0.5, 1.0]]))
    expected = -0.005 * math.exp(-0.5 * np.array([px, pz]) @ inv @ np.array([px, pz]))
    assert ref.surface_height(Surface("flat"), dent, 1.0, -1.0) == pytest.approx(
        expected, rel=1e-14
    )


# --------------------------------------------------------------------------- flat mirror
def test_flat_uv_equals_mirror_image_construction():
    """No defect: the reflected ray is the line from the camera's mirror image
    ``C' = (Cx, -Cy, Cz)`` through the hit point (to 1e-9 mm)."""
    for theta in (45.0, 12.0):
        scene = paper_scene("flat", theta_deg=theta, dmax=0.0).with_size(32)
        frame = ref.trace(scene)
        c = scene.camera.world_pose().position
        d = _spec_directions(scene.camera)
        p = c + (-c[1] / d[..., 1])[..., None] * d
        mirrored = c * np.array([1.0, -1.0, 1.0])
        uv = _plane_hit(scene, p, p - mirrored)
        inside = (np.abs(uv) <= 150.0).all(axis=-1)
        assert inside.all()
        assert frame.mask.all()
        np.testing.assert_allclose(frame.uv, uv, rtol=0, atol=1e-9)
        np.testing.assert_allclose(frame.image, ref.radiance(scene.emitter, uv[..., 1]), atol=1e-12)


@pytest.mark.parametrize("theta", [85.0, 45.0, 5.0])
def test_flat_centre_pixel_sees_the_emitter_centre(theta):
    scene = replace(
        paper_scene("flat", theta_deg=theta, dmax=0.0),
        camera=Camera(theta_deg=theta, width=5, height=5),
    )
    frame = ref.trace(scene)
    np.testing.assert_allclose(frame.uv[2, 2], [0.0, 0.0], atol=1e-9)
    assert frame.image[2, 2] == pytest.approx(ref.radiance(scene.emitter, 0.0), abs=1e-12)
    # symmetric about the centre column
    np.testing.assert_allclose(frame.uv[:, ::-1, 0], -frame.uv[:, :, 0], atol=1e-9)


def test_small_dent_displacement_matches_closed_form():
    """SPEC §6: for small slopes the largest emitter displacement is
    ``2 slope_max De``, ``slope_max = (dmax/σ) e^{-1/2}``."""
    scene = paper_scene("flat", theta_deg=45.0, sigma2=1.0, dmax=0.005).with_size(256)
    window = dict(rows=slice(96, 160), cols=slice(96, 160))  # the dent's neighbourhood
    v1 = ref.trace(scene, "uv", **window).uv[..., 1]
    v0 = ref.trace(scene.without_defect(), "uv", **window).uv[..., 1]
    expected = 2.0 * (0.005 / 1.0) * math.exp(-0.5) * 256.0
    assert np.max(np.abs(v1 - v0)) == pytest.approx(expected, rel=0.02)
    # the window holds the whole dent: its border is undisturbed
    edge = np.concatenate([(v1 - v0)[0], (v1 - v0)[-1], (v1 - v0)[:, 0], (v1 - v0)[:, -1]])
    assert np.max(np.abs(edge)) < 0.02 * expected


# --------------------------------------------------------------------------- curved
CURVED = [
    ("sphere", 70.0, "z", 45.0),
    ("sphere", -70.0, "z", 75.0),
    ("cylinder", 70.0, "z", 30.0),
    ("cylinder", -70.0, "z", 75.0),
    ("cylinder", 70.0, "x", 45.0),
    ("cylinder", -70.0, "x", 75.0),
]


def _analytic_surface(kind, radius, axis, p):
    """``(f(x, z), unit normal)`` from the centre of the sphere/cylinder."""
    a = abs(radius)
    s = 1.0 if radius > 0 else -1.0
    centre_y = -radius  # convex: below the apex; concave: above it
    rel = p - np.array([0.0, centre_y, 0.0])
    if kind == "cylinder":
        rel[..., 2 if axis == "z" else 0] = 0.0
    ax = p[..., 0] if axis == "z" or kind == "sphere" else np.zeros_like(p[..., 0])
    az = p[..., 2] if axis == "x" or kind == "sphere" else np.zeros_like(p[..., 2])
    f = s * (np.sqrt(a * a - ax * ax - az * az) - a)
    return f, s * rel / a


@pytest.mark.parametrize("kind,radius,axis,theta", CURVED)
def test_curved_hits_normals_and_reflection_law(kind, radius, axis, theta):
    scene = Scene(
        camera=Camera(theta_deg=theta).resampled(24),
        emitter=Emitter(period=10.0),
        surface=Surface(kind, radius, axis),
        defect=Defect(dmax=0.0),
    )
    origin, d = ref.pixel_rays(scene.camera)
    t, p, normals, valid = ref.first_hit(scene, origin, d)
    assert valid.mean() > 0.5
    f, n_true = _analytic_surface(kind, radius, axis, p[valid])
    np.testing.assert_allclose(p[valid][:, 1], f, rtol=0, atol=1e-10)
    np.testing.assert_allclose(normals[valid], n_true, rtol=0, atol=1e-12)
    assert (np.einsum("nk,nk->n", d[valid], n_true) < 0).all()  # hit from the front
    # just before the hit the ray is above the surface
    assert _gap_along(scene, origin, d[valid], t[valid] * (1 - 1e-9)).min() > 0
    # reflection law: the emitter point the tracer reports lies on the mirror ray
    frame = ref.trace(scene, ("uv", "mask"))
    assert frame.mask.sum() > 0.3 * frame.mask.size
    m = frame.mask & valid
    th = math.radians(theta)
    e = scene.emitter.distance * np.array([0.0, math.sin(th), -math.cos(th)])
    e_v = np.array([0.0, math.cos(th), math.sin(th)])
    q = e + frame.uv[m][:, [0]] * np.array([1.0, 0.0, 0.0]) + frame.uv[m][:, [1]] * e_v
    out = (q - p[m]) / np.linalg.norm(q - p[m], axis=1, keepdims=True)
    dn = np.einsum("nk,nk->n", d[m], n_true[m[valid]])
    np.testing.assert_allclose(out, d[m] - 2 * dn[:, None] * n_true[m[valid]], atol=1e-11)
    # angle of incidence == angle of reflection
    np.testing.assert_allclose(np.einsum("nk,nk->n", out, n_true[m[valid]]), -dn, atol=1e-11)


def test_sphere_silhouette_normals_stay_finite():
    """Rays that skim a convex sphere's rim get (nearly) horizontal, finite normals."""
    scene = Scene(surface=Surface("sphere", 5.0), defect=Defect(dmax=0.0))
    d = np.array([[0.0, 0.0, -1.0]])
    for lift in (1e-4, 1e-12):  # height of the ray above the rim (y = -R)
        t, p, n, valid = ref.first_hit(scene, np.array([0.0, -5.0 + lift, 50.0]), d)
        assert valid[0] and np.isfinite(n).all()
        assert p[0, 2] == pytest.approx(math.sqrt(25.0 - lift * lift), abs=1e-12)
        if lift == 1e-4:
            np.testing.assert_allclose(
                n[0], [0.0, lift / 5.0, math.sqrt(1 - (lift / 5.0) ** 2)], atol=1e-10
            )
        else:
            assert abs(n[0, 1]) < 1e-6 and n[0, 2] > 1 - 1e-12


def test_normals_match_finite_differences_with_anisotropic_defect():
    """``n ∝ (-h_x, 1, -h_z)`` against central differences of the public height."""
    scene = Scene(
        camera=Camera(theta_deg=40.0, pixel_pitch=0.04, width=9, height=9),  # about ±1.3 mm
        surface=Surface("sphere", 70.0),
        defect=Defect(dmax=0.02, sigma_x2=0.5, sigma_z2=0.25, sigma_xz=0.2, x0=0.3, z0=-0.2),
    )
    origin, d = ref.pixel_rays(scene.camera)
    t, p, n, valid = ref.first_hit(scene, origin, d)
    assert valid.all()
    x, z, eps = p[..., 0], p[..., 2], 1e-5

    def height(x, z):
        return ref.surface_height(scene.surface, scene.defect, x, z)

    hx = (height(x + eps, z) - height(x - eps, z)) / (2 * eps)
    hz = (height(x, z + eps) - height(x, z - eps)) / (2 * eps)
    expected = np.stack([-hx, np.ones_like(hx), -hz], axis=-1)
    expected /= np.linalg.norm(expected, axis=-1, keepdims=True)
    np.testing.assert_allclose(n, expected, atol=1e-9)
    assert np.abs(n[..., 0]).max() > 0.01  # the defect tilts the normals noticeably
    np.testing.assert_allclose(p[..., 1], height(x, z), atol=1e-12)


def test_rays_parallel_to_axes():
    """Degenerate directions: along a cylinder's axis, straight down onto a sphere."""
    none = Defect(dmax=0.0)
    # a vertical ray: the sphere's domain test has no x/z motion
    sphere = Scene(surface=Surface("sphere", 70.0), defect=none)
    t, p, n, valid = ref.first_hit(sphere, np.array([0.0, 50.0, 0.0]), np.array([[0.0, -1.0, 0.0]]))
    assert valid[0] and t[0] == pytest.approx(50.0, abs=1e-12)
    np.testing.assert_allclose(n[0], [0.0, 1.0, 0.0], atol=1e-15)
    # dz = 0 with the axis along x: the ray stays inside the slab |z| <= R for all t
    cyl = Scene(surface=Surface("cylinder", 70.0, "x"), defect=none)
    d = np.array([[1.0, -0.1, 0.0]])
    t, p, n, valid = ref.first_hit(cyl, np.array([0.0, 5.0, 30.0]), d)
    assert valid[0]
    assert p[0, 1] == pytest.approx(math.sqrt(70.0**2 - 30.0**2) - 70.0, abs=1e-12)
    # the centre column of an odd image has dx = 0 exactly: in the plane of a z-axis cylinder
    scene = Scene(
        camera=Camera(theta_deg=30.0, width=5, height=5),
        surface=Surface("cylinder", 70.0, "z"),
        defect=none,
    )
    origin, dirs = ref.pixel_rays(scene.camera)
    assert (dirs[:, 2, 0] == 0).all()
    t, p, n, valid = ref.first_hit(scene, origin, dirs)
    assert valid.all()
    np.testing.assert_allclose(p[:, 2, 1], 0.0, atol=1e-12)  # f(x = 0) = 0
    np.testing.assert_allclose(n[:, 2], np.tile([0.0, 1.0, 0.0], (5, 1)), atol=1e-15)


# --------------------------------------------------------------------------- occlusion
def test_deep_concave_bowl_hides_its_inside():
    """R = -20 seen at 5°: the camera sits below the rim and outside it; a ray that
    reaches the bowl meets the outer wall of the shell first (a crossing from below), so
    the inside is hidden and every pixel is a miss."""
    bowl = Scene(
        camera=Camera(theta_deg=5.0).resampled(16),
        surface=Surface("sphere", -20.0),
        defect=Defect(dmax=0.0),
    )
    origin, d = ref.pixel_rays(bowl.camera)
    # the rays do meet the sphere: a naive "first root" solver would report hits
    centre = np.array([0.0, 20.0, 0.0])
    oc = origin - centre
    b = d @ oc
    disc = b * b - (oc @ oc - 400.0)
    assert (disc[2:7, 6:10] > 0).all()  # rows above the centre aim into the ball
    frame = ref.trace(bowl)
    assert not frame.mask.any()
    assert (frame.image == 0).all() and np.isnan(frame.uv).all()
    assert not ref.first_hit(bowl, origin, d)[3].any()
    # seen from high up, the same bowl's inside is visible around the centre
    high = replace(bowl, camera=Camera(theta_deg=60.0).resampled(16))
    origin, d = ref.pixel_rays(high.camera)
    t, p, n, valid = ref.first_hit(high, origin, d)
    assert valid[6:10, 6:10].all()
    np.testing.assert_allclose(
        p[valid][:, 1], 20.0 - np.sqrt(400.0 - (p[valid][:, [0, 2]] ** 2).sum(1)), atol=1e-10
    )


def test_first_crossing_of_steep_bump_at_grazing_view():
    """A steep bump at 5°: rays can cross the height field several times; the hit must be
    the first crossing from above (g > 0 everywhere before it)."""
    scene = Scene(
        camera=Camera(theta_deg=5.0, pixel_pitch=0.0005, width=16, height=64),  # ~2.5 x 0.06 mm
        defect=Defect.isotropic_dent(-0.05, 0.05),
    )
    origin, d = ref.pixel_rays(scene.camera)
    t, p, n, valid = ref.first_hit(scene, origin, d)
    assert valid.all()
    multiple = 0
    s = np.linspace(0.0, 1.0, 20001)[:-1]
    for i, j in np.ndindex(valid.shape):
        before = _gap_along(scene, origin, d[i, j], t[i, j] * s)
        assert before.min() > 0, (i, j)
        after = _gap_along(scene, origin, d[i, j], t[i, j] + np.linspace(1e-6, 3.0, 3001))
        assert after[0] < 0
        multiple += bool((after > 0).any())
    assert multiple >= 10  # the case is a real test of "first"


@pytest.mark.parametrize("slope", [0.01, 0.03])
def test_grazing_dip_thinner_than_the_sampling_is_found(slope):
    """A ray that dips only 1e-9 mm into a bump's top hits there; one passing 1e-9 mm
    above it flies on to the plane far behind."""
    amp, s2 = 0.05, 0.05
    scene = Scene(defect=Defect.isotropic_dent(-amp, s2))

    def dg(z):  # d/dz of the gap y_c + slope z - amp exp(-z²/2s2)
        return slope + amp * z / s2 * math.exp(-z * z / (2 * s2))

    lo, hi = -math.sqrt(s2), 0.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if dg(mid) < 0 else (lo, mid)
    z_star = 0.5 * (lo + hi)  # tangent point of the ray family
    d = np.array([[0.0, -slope, -1.0]]) / math.hypot(slope, 1.0)
    for depth, near in ((1e-9, True), (-1e-9, False)):
        y_c = -slope * z_star + amp * math.exp(-z_star * z_star / (2 * s2)) - depth
        o = np.array([0.0, y_c + slope * 30.0, 30.0])
        t, p, n, valid = ref.first_hit(scene, o, d)
        assert valid[0]
        assert (abs(p[0, 2] - z_star) < 1e-3) == near


# --------------------------------------------------------------------------- frames
def test_supersampling_is_the_mean_of_a_finer_camera():
    """SPEC/frame convention, n = 2: image = mean of the 4 sub-pixel renders, uv = mean of
    the samples that reach the emitter, mask = any. Built from a camera with twice the
    resolution and half the pitch (its pixels are the sub-pixel samples)."""
    base = paper_scene("sphere", theta_deg=35.0, sigma2=4.0, dmax=0.02)
    base = replace(base, emitter=replace(base.emitter, half_size=(60.0, 45.0)))
    coarse = replace(base.with_size(16), render=RenderSettings(supersample=2))
    fine = base.with_size(32)
    a = ref.trace(coarse)
    b = ref.trace(fine)

    def blocks(x):
        return x.reshape(16, 2, 16, 2, *x.shape[2:]).swapaxes(1, 2).reshape(16, 16, 4, *x.shape[2:])

    np.testing.assert_allclose(a.image, blocks(b.image).mean(axis=2), atol=1e-13)
    count = blocks(b.mask).sum(axis=2)
    assert ((count > 0) & (count < 4)).sum() >= 4  # partially covered pixels exist
    np.testing.assert_array_equal(a.mask, count > 0)
    uv_sum = np.where(blocks(b.mask)[..., None], blocks(b.uv), 0.0).sum(axis=2)
    with np.errstate(invalid="ignore"):
        expected = uv_sum / count[..., None]
    np.testing.assert_allclose(a.uv, expected, atol=1e-10)  # NaN where count == 0
    assert np.isnan(a.uv[count == 0]).all()


def test_window_outputs_and_emitter_edges():
    scene = paper_scene("cylinder", theta_deg=25.0, sigma2=4.0, dmax=0.005).with_size(32)
    scene = replace(scene, emitter=replace(scene.emitter, half_size=(150.0, 20.0)))
    full = ref.trace(scene)
    assert isinstance(full, Frame) and full.image.dtype == np.float64 and full.mask.dtype == bool
    part = ref.trace(scene, ("uv",), rows=slice(3, 17), cols=slice(10, 31))
    assert part.image is None and part.mask is None and part.uv.shape == (14, 21, 2)
    np.testing.assert_array_equal(part.uv, full.uv[3:17, 10:31])
    # the short emitter cuts the image: misses are black, NaN, unmasked
    assert 0 < full.mask.mean() < 1
    assert (full.image[~full.mask] == 0).all()
    assert np.isnan(full.uv[~full.mask]).all() and not np.isnan(full.uv[full.mask]).any()
    assert (np.abs(full.uv[full.mask][:, 1]) <= 20.0).all()


# --------------------------------------------------------------------------- Blinn-Phong
def _blinn_phong_mirror_space(scene: Scene, p, d, normal, points=601, span=9.0) -> float:
    """Independent Blinn-Phong quadrature over the light direction ``l`` (the tracer
    integrates over the half vector): a gnomonic grid ``l ∝ r + α t1 + β t2`` around the
    mirror direction, ``t1`` in the plane of incidence (lobe std 2/sqrt(n)), ``t2`` across
    (std 2 cos θ_i / sqrt(n)), ``dω = dα dβ (1 + α² + β²)^{-3/2}``, trapezoid rule."""
    n = scene.render.shininess
    wo = -d
    r = d - 2.0 * (d @ normal) * normal
    t2 = np.cross(normal, r)
    t2 /= np.linalg.norm(t2)
    t1 = np.cross(t2, r)
    cos_i = wo @ normal
    alpha = np.linspace(-1.0, 1.0, points) * math.tan(span * 2.0 / math.sqrt(n))
    beta = np.linspace(-1.0, 1.0, points) * math.tan(span * 2.0 * cos_i / math.sqrt(n))
    aa, bb = np.meshgrid(alpha, beta, indexing="ij")
    rr = 1.0 + aa * aa + bb * bb
    light = (r + aa[..., None] * t1 + bb[..., None] * t2) / np.sqrt(rr)[..., None]
    half = light + wo
    cos_h = (half @ normal) / np.linalg.norm(half, axis=-1)
    weight = np.maximum(cos_h, 0.0) ** n * rr**-1.5
    trap = np.ones(points)
    trap[[0, -1]] = 0.5
    weight = weight * trap[:, None] * trap[None, :]
    _, v, ok = ref.emitter_coordinates(scene, p, light)
    lum = np.where(ok, ref.radiance(scene.emitter, np.where(ok, v, 0.0)), 0.0)
    return float(np.sum(lum * weight) / np.sum(weight))


@pytest.mark.parametrize(
    "kind,theta,phase,pixel,shininess",
    [
        ("flat", 45.0, 0.5, (4, 4), 1e6),
        ("flat", 15.0, 0.0, (1, 6), 1e6),
        ("flat", 5.0, 0.3, (2, 2), 1e6),
        ("sphere", 45.0, 0.5, (2, 6), 1e6),
        ("sphere", 25.0, 0.4, (5, 3), 1e5),
    ],
)
def test_blinn_phong_matches_mirror_space_quadrature(kind, theta, phase, pixel, shininess):
    scene = paper_scene(kind, theta_deg=theta, dmax=0.0, phase=phase).with_size(9)
    scene = replace(scene, render=RenderSettings(reflection="blinn-phong", shininess=shininess))
    rows, cols = slice(pixel[0], pixel[0] + 1), slice(pixel[1], pixel[1] + 1)
    value = ref.trace(scene, "image", rows=rows, cols=cols).image[0, 0]
    origin, d = ref.pixel_rays(scene.camera, rows, cols)
    t, p, n, valid = ref.first_hit(scene, origin, d)
    expected = _blinn_phong_mirror_space(scene, p[0, 0], d[0, 0], n[0, 0])
    assert 0.05 < expected < 0.95  # on a stripe's flank: sensitive to any error
    assert value == pytest.approx(expected, abs=1e-10)


def test_blinn_phong_converges_to_mirror():
    base = paper_scene("flat", dmax=0.0).with_size(16)
    mirror = ref.trace(base, "image").image
    diffs = []
    for n in (1e6, 1e8):
        bp = ref.trace(
            replace(base, render=RenderSettings(reflection="blinn-phong", shininess=n)), "image"
        ).image
        diffs.append(np.max(np.abs(bp - mirror)))
    assert diffs[0] > 0.05  # the lobe (0.5 mm on the emitter) blurs 0.42 mm stripes
    assert diffs[1] < 0.02 and diffs[1] < diffs[0] / 10


def test_blinn_phong_uniform_emitter_gives_one():
    """Stripes 20 periods wide overlap into a uniform emitter (L = σ sqrt(2π)/period to
    1e-300); the normalised lobe must return exactly that, on a curved, dented surface."""
    scene = paper_scene("sphere", theta_deg=45.0, dmax=0.005).with_size(6)
    scene = replace(
        scene,
        emitter=Emitter(period=2.0, stripe_sigma=40.0, half_size=(1e4, 1e4)),
        render=RenderSettings(reflection="blinn-phong", shininess=1e3),
    )
    level = 40.0 * math.sqrt(2.0 * math.pi) / 2.0
    window = dict(rows=slice(1, 6), cols=slice(0, 6))
    frame = ref.trace(scene, **window)
    assert frame.mask.all()
    np.testing.assert_allclose(frame.image / level, 1.0, rtol=0, atol=1e-12)


def test_blinn_phong_rejects_tiny_exponents():
    scene = replace(
        paper_scene("flat").with_size(2),
        render=RenderSettings(reflection="blinn-phong", shininess=10.0),
    )
    with pytest.raises(SceneError, match="render.shininess"):
        ref.trace(scene, "image")
