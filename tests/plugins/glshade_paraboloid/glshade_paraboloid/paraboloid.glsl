// Base surface (plug-in glshade-paraboloid): the paraboloid of revolution
// y = -(X^2 + Z^2) / (2 R) about the gaze point, (X, Z) = p.xz + u_surface_axis_xz the
// world coordinates of the local point p. R > 0: a dome (convex); R < 0: a bowl.
uniform real u_surface_focal_radius;  // signed R, mm (the radius of curvature at the apex)
uniform real2 u_surface_axis_xz;      // (x0, z0): local -> world offset of the axis, mm

real2 paraboloid_xz(real3 p) { return p.xz + u_surface_axis_xz; }

// First crossing from above of y = f + shift along o + t d, t > tmin; t_far: where the ray
// is back above (1e30: never).
// g(t) = y - f - shift = (a t^2 + 2 b t + c) / (2 R) with a = |d.xz|^2,
// b = q.d.xz + R d.y, c = |q|^2 + 2 R h (q = world xz of o, h = o.y - shift).
// R > 0: g > 0 outside the roots: the ray comes down through the near root and is back
// above at the far one; starting below the dome (tmin past the near root) it has no
// crossing from above. R < 0: g > 0 between the roots (inside the bowl): the crossing from
// above is the far root, and a ray still below the bowl's wall at tmin (the near root
// beyond tmin) is hidden by it. A vertical ray (a = 0) meets the surface once, going down.
bool base_hit(real3 o, real3 d, real shift, real tmin, out real t, out real t_far) {
    real R = u_surface_focal_radius;
    real2 q = paraboloid_xz(o);
    real h = o.y - shift;
    real a = dot(d.xz, d.xz);
    real b = dot(q, d.xz) + R * d.y;
    real c = dot(q, q) + 2.0 * R * h;
    t_far = 1.0e30;
    if (a == 0.0) {                       // vertical: 2 b t + c = 0, b = R d.y
        if (d.y >= 0.0) return false;
        t = -0.5 * c / b;
        return t > tmin;
    }
    real t1, t2;
    if (!stable_quadratic(a, b, c, t1, t2)) return false;   // no real root: never crosses
    real t_near = min(t1, t2);
    real t_exit = max(t1, t2);
    if (R > 0.0) {
        t = t_near;
        t_far = t_exit;
        return t_near > tmin;
    }
    t = t_exit;
    return t_near <= tmin && t_exit > tmin;
}

real base_height(real3 p) {
    real2 q = paraboloid_xz(p);
    return -0.5 * dot(q, q) / u_surface_focal_radius;
}

// Bound on |f''| along a horizontal unit direction (1/mm): the Hessian is -I / R.
real base_curvature(real3 p) { return 1.0 / abs(u_surface_focal_radius); }

real2 base_slope(real3 p) { return -paraboloid_xz(p) / u_surface_focal_radius; }

// (-(f_x + D_x), 1, -(f_z + D_z)), f_x = -X / R, f_z = -Z / R.
real3 base_normal(real3 p, real depth, real2 dent_grad) {
    real2 q = paraboloid_xz(p) / u_surface_focal_radius;
    return real3(q.x - dent_grad.x, 1.0, q.y - dent_grad.y);
}
