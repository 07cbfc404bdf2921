// First crossing from above of y = f + D (SPEC §4, §5).
// Bracket: D lies between lo = min(0, -dmax) and hi = max(0, -dmax), so the ray meets
// f + hi first and f + lo last; the first root of g(s) = y - f - D lies between them.
//
// The march never passes a root. With K a bound on |g''| along the ray (the dent's
// |D''| <= |dmax| / sigma_min^2 and the base surface's curvature, times the ray's
// horizontal extent squared), g(s + h) >= g + g' h - K h^2 / 2, which stays positive for
// every h below
//     h_safe = 2 g / (sqrt(g'^2 + 2 K g) - g').
// Approaching a transversal root h_safe ~ g / |g'| (quadratic convergence from above,
// like Newton, but never overshooting); near a ray that skims a bump without crossing
// it the steps stay ~ sqrt(2 g / K) and grow again past the closest approach. A step
// that lands on g <= 0 (rounding, or a bound a step too optimistic near a silhouette)
// brackets the root, which Newton safeguarded by bisection then polishes.
uniform real u_dent_lo;         // min(0, -dmax), mm
uniform real u_dent_hi;         // max(0, -dmax), mm
uniform real u_dent_curvature;  // |dmax| * lambda_max(S^-1): bound on |D''|, 1/mm
uniform int u_march_steps;      // most steps of the march
uniform int u_newton_iterations;
uniform real u_root_tol;        // mm along the ray
{$ if "iterations" in outputs $}
int g_evaluations;              // per trace, for the "iterations" output
{$ endif $}

// g = y - f - D at p, and its derivative along d.
real surface_gap(real3 p, real3 d, out real slope) {
{$ if "iterations" in outputs $}
    g_evaluations += 1;
{$ endif $}
    real2 grad;
    real depth = dent(p, grad);
    slope = d.y - dot(base_slope(p) + grad, d.xz);
    return p.y - base_height(p) - depth;
}

bool surface_hit(real3 o, real3 d, real tmin, out real3 p, out real depth, out real2 dent_grad) {
    real t_hi, t_hi_far, t_lo, t_lo_far;
    if (!base_hit(o, d, u_dent_hi, tmin, t_hi, t_hi_far)) return false;
    bool lo_ok = base_hit(o, d, u_dent_lo, tmin, t_lo, t_lo_far);
    real span = lo_ok ? t_lo - t_hi : t_hi_far - t_hi;
    if (!(span < 1.0e29)) return false;
    span = max(span, 0.0);
    real3 start = o + t_hi * d;           // re-origin at the upper bracket: small numbers
    // steps under an ulp of the point leave g unchanged: the march's resolution
    real resolution = 2.0 * REAL_EPS * max(max(abs(start.x), abs(start.y)), abs(start.z));
    real k2 = dot(d.xz, d.xz) * (u_dent_curvature + max(base_curvature(start), base_curvature(start + span * d)));

    real slope;
    real g = surface_gap(start, d, slope);
    real s = 0.0, a = 0.0, b = 0.0, g_a = g, g_b = g;
    bool crossed = g <= 0.0;
    bool converged = false;
    for (int i = 0; i < u_march_steps && !crossed && !converged && s < span; ++i) {
        real h = 2.0 * g / (sqrt(slope * slope + 2.0 * k2 * g) - slope);
        if (!(h >= 0.0)) h = span - s;    // K = 0 and g' >= 0: g cannot fall to 0 here
        h = min(h, span - s);
        if (h <= max(u_root_tol, resolution + 2.0 * REAL_EPS * s)) {
            converged = true;             // within the resolution of the root, from above
            break;
        }
        a = s;
        g_a = g;
        s += h;
        g = surface_gap(start + s * d, d, slope);
        if (g <= 0.0) {
            crossed = true;
            b = s;
            g_b = g;
        }
    }
    if (!crossed && !converged) {
        if (s < span) {
            // the march ran out of steps (a ray skimming a silhouette): settle for a
            // root of the rest of the bracket, if it has one
            a = s;
            g_a = g;
        }
        if (!lo_ok) return false;         // passed between f + hi and f + lo: no crossing
        b = span;
        g_b = surface_gap(start + span * d, d, slope);
        if (g_b > 0.0) {                  // rounding at the lower bracket: take its end
            a = b;
            g_a = g_b;
        }
    }
    real x = s;
    if (!converged && b > a) {
        x = (g_a > g_b) ? a + (b - a) * g_a / (g_a - g_b) : a;   // regula falsi start
        for (int it = 0; it < u_newton_iterations && b > a; ++it) {
            real gx = surface_gap(start + x * d, d, slope);
            if (gx > 0.0) a = x; else b = x;
            real next = (slope != 0.0) ? x - gx / slope : 0.5 * (a + b);
            // x itself is now an end of [a, b]: a converged step lands on it, so the
            // closed bracket is the test (the open one would bisect away from the root).
            if (!(next >= a && next <= b)) next = 0.5 * (a + b);
            bool done = abs(next - x) <= max(u_root_tol, resolution + 2.0 * REAL_EPS * abs(x));
            x = next;
            if (done || gx == 0.0) break;
        }
    } else if (!converged) {
        x = a;
    }
    p = start + x * d;
    depth = dent(p, dent_grad);
    return true;
}
