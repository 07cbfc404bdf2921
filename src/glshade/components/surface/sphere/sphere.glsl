// Base surface: sphere y = sqrt(R^2 - x^2 - z^2) - R (R < 0: concave bowl).
// Sag form f = -s r^2 / (|R| + w), w = sqrt(R^2 - r^2), s = sign(R): no cancellation
// near the apex, where f is micrometres and R^2 is 4900.
uniform real u_surface_radius;    // signed R, mm
uniform real2 u_surface_axis_xz;  // (x0, z0): local -> world offset of the sphere's axis, mm

real2 sphere_xz(real3 p) { return real2(p.x + u_surface_axis_xz.x, p.z + u_surface_axis_xz.y); }

// First crossing from above of y = f + shift along o + t d, t > tmin (lib/quadric.glsl).
bool base_hit(real3 o, real3 d, real shift, real tmin, out real t, out real t_far) {
    real R = u_surface_radius;
    real2 q = sphere_xz(o);
    real h = o.y - shift;                       // height above the shifted apex plane
    // |o - centre|^2 - R^2 with centre = (axis, shift - R): R^2 cancelled analytically.
    real c = q.x * q.x + q.y * q.y + h * h + 2.0 * R * h;
    real b = q.x * d.x + q.y * d.z + (h + R) * d.y;
    real t1, t2;
    if (!stable_quadratic(1.0, b, c, t1, t2)) return false;
    real t_near = min(t1, t2);
    real t_exit = max(t1, t2);
    return first_crossing(R, t_near, t_exit, h + R + t_near * d.y, h + R + t_exit * d.y, tmin, t, t_far);
}

real base_height(real3 p) {
    real2 q = sphere_xz(p);
    real r2 = dot(q, q);
    real w = sqrt(max(u_surface_radius * u_surface_radius - r2, 0.0));
    return -sign(u_surface_radius) * r2 / (abs(u_surface_radius) + w);
}

// Bound on |f''| along a horizontal unit direction at p (1/mm): the Hessian's largest
// eigenvalue, R^2 / w^3 (radial; the tangential one is 1 / w).
real base_curvature(real3 p) {
    real2 q = sphere_xz(p);
    real w = sqrt(max(u_surface_radius * u_surface_radius - dot(q, q), REAL_EPS));
    return u_surface_radius * u_surface_radius / (w * w * w);
}

real2 base_slope(real3 p) {
    real2 q = sphere_xz(p);
    real w = sqrt(max(u_surface_radius * u_surface_radius - dot(q, q), REAL_EPS));
    return -sign(u_surface_radius) * q / w;
}

// (-h_x, 1, -h_z) multiplied by w = sqrt(R^2 - r^2): finite up to the silhouette.
// On the surface w = s (y - D) + |R| (the height above the centre): taken from the
// height it is well conditioned near the silhouette, where R^2 - r^2 cancels.
real3 base_normal(real3 p, real depth, real2 dent_grad) {
    real2 q = sphere_xz(p);
    real s = sign(u_surface_radius);
    real w = max(s * (p.y - depth) + abs(u_surface_radius), 0.0);
    return real3(s * q.x - w * dent_grad.x, w, s * q.y - w * dent_grad.y);
}
