// Base surface: y = f(x, z) written as a formula (paper eq. 3). formula_values below is
// printed from the checked expression tree and its exact gradient (formula/printers.py:
// one statement per distinct node), never user text; x, z are world mm (local +
// u_surface_origin).
{$ for name in formula_parameters $}
uniform real u_surface_p_{{ name }};
{$ endfor $}
uniform real3 u_surface_origin;    // the local frame's origin in world mm
uniform real u_surface_lo;         // f lies in [lo, hi] where the camera looks (mm)
uniform real u_surface_hi;
uniform real u_surface_curvature;  // bound on |f''| along horizontal unit directions (1/mm)

{{ formula_functions }}

// (f, f_x, f_z) at (x, z).
real3 formula_values(real x, real z) {
{{ formula_body }}
}
real formula_f(real x, real z) { return formula_values(x, z).x; }
real2 formula_grad(real x, real z) { return formula_values(x, z).yz; }

// g = y - f - shift at p (local), and its derivative along d (lib/freeform.glsl).
real freeform_gap(real3 p, real3 d, real shift, out real slope) {
    real3 w = p + u_surface_origin;
    real3 values = formula_values(w.x, w.z);
    slope = d.y - dot(values.yz, d.xz);
    return w.y - values.x - shift;
}

// First crossing from above of y = f + shift along o + t d, t > tmin; t_far: where the
// ray leaves the slab lo + shift <= y <= hi + shift (beyond it there is no crossing).
bool base_hit(real3 o, real3 d, real shift, real tmin, out real t, out real t_far) {
    real enter, leave;
    bool inside = freeform_slab(o, d, u_surface_hi + shift - u_surface_origin.y,
                                u_surface_lo + shift - u_surface_origin.y, tmin, enter, leave);
    t_far = leave;
    real s;
    if (!inside || !freeform_march(o + enter * d, d, shift, leave - enter, u_surface_curvature, s)) return false;
    t = enter + s;
    return true;
}

real base_height(real3 p) {
    real3 w = p + u_surface_origin;
    return formula_f(w.x, w.z) - u_surface_origin.y;
}
// Bound on |f''| along a horizontal unit direction at p (1/mm).
real base_curvature(real3 p) { return u_surface_curvature; }
real2 base_slope(real3 p) {
    real3 w = p + u_surface_origin;
    return formula_grad(w.x, w.z);
}

// Unnormalised normal of y = f + D at p, given D and grad D = (D_x, D_z).
real3 base_normal(real3 p, real depth, real2 dent_grad) {
    real2 slope = base_slope(p) + dent_grad;
    return real3(-slope.x, 1.0, -slope.y);
}
