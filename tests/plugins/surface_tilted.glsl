// A toy base surface for the tests: the plane y = s z (world), s = tan(tilt).
uniform real u_surface_slope;    // s = dy/dz
uniform real u_surface_z0;       // local -> world offset along z, mm

// First crossing from above of y = f + shift along o + t d with t > tmin.
bool base_hit(real3 o, real3 d, real shift, real tmin, out real t, out real t_far) {
    t_far = 1.0e30;
    real falling = d.y - u_surface_slope * d.z;
    if (falling >= 0.0) return false;
    t = (shift + u_surface_slope * (o.z + u_surface_z0) - o.y) / falling;
    return t > tmin;
}

real base_height(real3 p) { return u_surface_slope * (p.z + u_surface_z0); }
real base_curvature(real3 p) { return 0.0; }
real2 base_slope(real3 p) { return real2(0.0, u_surface_slope); }
real3 base_normal(real3 p, real depth, real2 dent_grad) {
    return real3(-dent_grad.x, 1.0, -(u_surface_slope + dent_grad.y));
}
