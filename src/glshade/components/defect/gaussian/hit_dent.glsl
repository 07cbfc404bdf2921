// First crossing from above of y = f + D.
// Bracket: D lies between lo = min(0, -dmax) and hi = max(0, -dmax), so the ray meets
// f + hi first and f + lo last; the first root of g(s) = y - f - D lies between them.
// The march never passes a root (lib/march.glsl: K bounds |g''| along the ray with the
// dent's |D''| <= |dmax| / sigma_min^2 and the base surface's curvature, times the ray's
// horizontal extent squared). A step that lands on g <= 0 (rounding, or a bound a step
// too optimistic near a silhouette) brackets the root, which Newton safeguarded by
// bisection then polishes.
{$ import "lib/march.glsl" as march $}
uniform real u_defect_lo;         // min(0, -dmax), mm
uniform real u_defect_hi;         // max(0, -dmax), mm
uniform real u_defect_curvature;  // |dmax| * lambda_max(S^-1): bound on |D''|, 1/mm
uniform int u_defect_march_steps; // most steps of the march
uniform int u_defect_newton_iterations;
uniform real u_defect_tol;        // mm along the ray

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
    if (!base_hit(o, d, u_defect_hi, tmin, t_hi, t_hi_far)) return false;
    bool lo_ok = base_hit(o, d, u_defect_lo, tmin, t_lo, t_lo_far);
    real span = lo_ok ? t_lo - t_hi : t_hi_far - t_hi;
    if (!(span < 1.0e29)) return false;
    span = max(span, 0.0);
    real3 start = o + t_hi * d;           // re-origin at the upper bracket: small numbers
    // steps under an ulp of the point leave g unchanged: the march's resolution
    real resolution = 2.0 * REAL_EPS * max(max(abs(start.x), abs(start.y)), abs(start.z));
    real k2 = dot(d.xz, d.xz) * (u_defect_curvature + max(base_curvature(start), base_curvature(start + span * d)));

    real slope;
    real g = surface_gap(start, d, slope);
    real s = 0.0, a = 0.0, b = 0.0, g_a = g, g_b = g;
    bool crossed = g <= 0.0;
    bool converged = false;
{$ call(point) march.safe_march("u_defect_march_steps", "u_defect_tol", false) $}surface_gap({{ point }}, d, slope){$ endcall $}
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
{$ call(point) march.newton_bisection("u_defect_newton_iterations", "u_defect_tol") $}surface_gap({{ point }}, d, slope){$ endcall $}
    } else if (!converged) {
        x = a;
    }
    p = start + x * d;
    depth = dent(p, dent_grad);
    return true;
}
