// Base surface: y = f(x, z) written as a formula (paper eq. 3). f, f_x and f_z below are
// SymPy's printing of the checked expression tree (glshade.formula), never user text;
// x, z are world mm (local + u_formula_origin).
{$ for name in formula_parameters $}
uniform real p_{{ name }};
{$ endfor $}
uniform real3 u_formula_origin;    // the local frame's origin in world mm
uniform real u_formula_lo;         // f lies in [lo, hi] where the camera looks (mm)
uniform real u_formula_hi;
uniform real u_formula_curvature;  // bound on |f''| along horizontal unit directions (1/mm)
uniform int u_formula_steps;       // most steps of the march
uniform real u_formula_tol;        // mm along the ray

real formula_f(real x, real z) { return {{ formula_f }}; }
real2 formula_grad(real x, real z) { return real2({{ formula_fx }}, {{ formula_fz }}); }

// g = y - f - shift at p (local), and its derivative along d.
real formula_gap(real3 p, real3 d, real shift, out real slope) {
    real3 w = p + u_formula_origin;
    slope = d.y - dot(formula_grad(w.x, w.z), d.xz);
    return w.y - formula_f(w.x, w.z) - shift;
}

// First crossing from above of y = f + shift along o + t d, t > tmin; t_far: where the
// ray leaves the slab lo + shift <= y <= hi + shift (beyond it there is no crossing).
// The march is the dent solve's (surface_hit_dent.glsl): with K = |d.xz|^2 u_formula_curvature
// bounding |g''|, a step h = 2 g / (sqrt(g'^2 + 2 K g) - g') never passes a root; a step
// landing on g <= 0 brackets the first one, which Newton safeguarded by bisection polishes.
bool base_hit(real3 o, real3 d, real shift, real tmin, out real t, out real t_far) {
    real top = u_formula_hi + shift - u_formula_origin.y;
    real bottom = u_formula_lo + shift - u_formula_origin.y;
    real enter, leave;
    if (d.y < 0.0) {
        enter = (top - o.y) / d.y;
        leave = (bottom - o.y) / d.y;
    } else if (d.y > 0.0) {
        enter = (bottom - o.y) / d.y;
        leave = (top - o.y) / d.y;
    } else {
        if (o.y > top || o.y < bottom) return false;
        enter = tmin;
        leave = tmin + 1.0e4;
    }
    real a = max(enter, tmin);
    t_far = leave;
    if (!(a < leave)) return false;
    real span = leave - a;
    real3 start = o + a * d;
    real k2 = dot(d.xz, d.xz) * u_formula_curvature;
    real resolution = 2.0 * REAL_EPS * max(max(abs(start.x), abs(start.y)), abs(start.z));
    real slope;
    real g = formula_gap(start, d, shift, slope);
    if (!(g > 0.0)) return false;     // starts below the surface (or where f is undefined)
    real s = 0.0, lo = 0.0, hi = 0.0, g_lo = g, g_hi = g;
    bool crossed = false;
    for (int i = 0; i < u_formula_steps && !crossed && s < span; ++i) {
        real h = 2.0 * g / (sqrt(slope * slope + 2.0 * k2 * g) - slope);
        if (!(h >= 0.0)) h = span - s;  // K = 0 and g' >= 0: g cannot fall to 0 here
        h = min(h, span - s);
        if (h <= max(u_formula_tol, resolution + 2.0 * REAL_EPS * s)) {
            t = a + s;                    // within the resolution of the root, from above
            return true;
        }
        lo = s;
        g_lo = g;
        s += h;
        g = formula_gap(start + s * d, d, shift, slope);
        if (!(g > 0.0)) {
            crossed = true;
            hi = s;
            g_hi = g;
        }
    }
    if (!crossed) return false;       // left the slab above the surface, or ran out of steps
    real x = (g_hi < 0.0) ? lo + (hi - lo) * g_lo / (g_lo - g_hi) : 0.5 * (lo + hi);
    for (int it = 0; it < 64 && hi > lo; ++it) {
        real gx = formula_gap(start + x * d, d, shift, slope);
        if (gx > 0.0) lo = x; else hi = x;
        real next = (slope != 0.0) ? x - gx / slope : 0.5 * (lo + hi);
        if (!(next >= lo && next <= hi)) next = 0.5 * (lo + hi);
        bool done = abs(next - x) <= max(u_formula_tol, resolution + 2.0 * REAL_EPS * abs(x));
        x = next;
        if (done || gx == 0.0) break;
    }
    t = a + x;
    return true;
}

real base_height(real3 p) {
    real3 w = p + u_formula_origin;
    return formula_f(w.x, w.z) - u_formula_origin.y;
}
// Bound on |f''| along a horizontal unit direction at p (1/mm).
real base_curvature(real3 p) { return u_formula_curvature; }
real2 base_slope(real3 p) {
    real3 w = p + u_formula_origin;
    return formula_grad(w.x, w.z);
}

// Unnormalised normal of y = f + D at p, given D and grad D = (D_x, D_z).
real3 base_normal(real3 p, real depth, real2 dent_grad) {
    real2 slope = base_slope(p) + dent_grad;
    return real3(-slope.x, 1.0, -slope.y);
}
