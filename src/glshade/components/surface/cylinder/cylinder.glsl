// Base surface: cylinder of signed radius R (R < 0: concave trough).
uniform real u_surface_radius;    // signed R, mm
uniform real u_surface_axis_off;  // local -> world offset of the coordinate across the axis, mm
{$ if cylinder_axis == "z" $}
// z (the plane of incidence): f = sqrt(R^2 - x^2) - R, across = x.
real cyl_across(real3 p) { return p.x + u_surface_axis_off; }
real cyl_dir(real3 d) { return d.x; }
real2 cyl_slope(real g) { return real2(g, 0.0); }
{$ else $}
// x (across the plane of incidence): f = sqrt(R^2 - z^2) - R, across = z.
real cyl_across(real3 p) { return p.z + u_surface_axis_off; }
real cyl_dir(real3 d) { return d.z; }
real2 cyl_slope(real g) { return real2(0.0, g); }
{$ endif $}
// Sag form f = -s a^2 / (|R| + w), w = sqrt(R^2 - a^2): see the sphere's sphere.glsl.

bool base_hit(real3 o, real3 d, real shift, real tmin, out real t, out real t_far) {
    real R = u_surface_radius;
    real a0 = cyl_across(o);
    real da = cyl_dir(d);
    real h = o.y - shift;
    real A = da * da + d.y * d.y;                 // not 1: the axis component drops out
    if (A <= REAL_EPS * REAL_EPS) return false;   // ray along the axis
    real c = a0 * a0 + h * h + 2.0 * R * h;
    real b = a0 * da + (h + R) * d.y;
    real t1, t2;
    if (!stable_quadratic(A, b, c, t1, t2)) return false;
    real t_near = min(t1, t2);
    real t_exit = max(t1, t2);
    return first_crossing(R, t_near, t_exit, h + R + t_near * d.y, h + R + t_exit * d.y, tmin, t, t_far);
}

real base_height(real3 p) {
    real a = cyl_across(p);
    real w = sqrt(max(u_surface_radius * u_surface_radius - a * a, 0.0));
    return -sign(u_surface_radius) * a * a / (abs(u_surface_radius) + w);
}

// Bound on |f''| along a horizontal unit direction at p (1/mm): R^2 / w^3.
real base_curvature(real3 p) {
    real a = cyl_across(p);
    real w = sqrt(max(u_surface_radius * u_surface_radius - a * a, REAL_EPS));
    return u_surface_radius * u_surface_radius / (w * w * w);
}

real2 base_slope(real3 p) {
    real a = cyl_across(p);
    real w = sqrt(max(u_surface_radius * u_surface_radius - a * a, REAL_EPS));
    return cyl_slope(-sign(u_surface_radius) * a / w);
}

// w = sqrt(R^2 - a^2) taken from the height, as for the sphere.
real3 base_normal(real3 p, real depth, real2 dent_grad) {
    real a = cyl_across(p);
    real w = max(sign(u_surface_radius) * (p.y - depth) + abs(u_surface_radius), 0.0);
    real2 tilt = cyl_slope(sign(u_surface_radius) * a);   // -f_slope * w
    return real3(tilt.x - w * dent_grad.x, w, tilt.y - w * dent_grad.y);
}
