// Base surface: the plane y = 0.

// First crossing from above of y = f + shift along o + t d with t > tmin.
// t_far: where the ray is back above the shifted surface (never, for a plane).
bool base_hit(real3 o, real3 d, real shift, real tmin, out real t, out real t_far) {
    t_far = 1.0e30;
    if (d.y >= 0.0) return false;  // parallel, or going up: crosses from below or never
    t = (shift - o.y) / d.y;
    return t > tmin;
}

real base_height(real3 p) { return 0.0; }
// Bound on |f''| along a horizontal unit direction at p (1/mm): a plane has none.
real base_curvature(real3 p) { return 0.0; }
real2 base_slope(real3 p) { return real2(0.0); }

// Unnormalised normal of y = f + D at p, given D and grad D = (D_x, D_z).
real3 base_normal(real3 p, real depth, real2 dent_grad) { return real3(-dent_grad.x, 1.0, -dent_grad.y); }
