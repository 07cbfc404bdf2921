// First crossing from above of y = f + D (SPEC §4, §5).
// Bracket: D lies between lo = min(0, -dmax) and hi = max(0, -dmax), so the ray meets
// f + hi first and f + lo last; the first root of g(s) = y - f - D lies between them.
// The bracket is scanned in u_scan_steps pieces for the FIRST sign change (a steep dent
// seen at a grazing angle can be crossed more than once), then refined by Newton's
// method, safeguarded by bisection so it never leaves the bracket.
uniform real u_dent_lo;       // min(0, -dmax), mm
uniform real u_dent_hi;       // max(0, -dmax), mm
uniform int u_scan_steps;     // >= 1
uniform int u_newton_iterations;
uniform real u_root_tol;      // mm along the ray

{$ if "iterations" in outputs $}
int g_evaluations;                            // per trace, for the "iterations" output
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
    real slope;
    real a = 0.0, b = 0.0;
    real g_a = surface_gap(start, d, slope);
    real g_b = g_a;
    bool found = g_a <= 0.0;
    real step = span / real(u_scan_steps);
    for (int i = 1; i <= u_scan_steps && !found; ++i) {
        real s = (i == u_scan_steps) ? span : step * real(i);
        real g = surface_gap(start + s * d, d, slope);
        if (g <= 0.0) {
            b = s;
            g_b = g;
            found = true;
        } else {
            a = s;
            g_a = g;
        }
    }
    if (!found) {
        if (!lo_ok) return false;         // passed between f + hi and f + lo: no crossing
        a = b = span;                     // rounding at the lower bracket: take its end
    }
    real x = (g_a > g_b) ? a + (b - a) * g_a / (g_a - g_b) : a;   // regula falsi start
    real resolution = 2.0 * REAL_EPS * max(max(abs(start.x), abs(start.y)), abs(start.z));
    for (int it = 0; it < u_newton_iterations && b > a; ++it) {
        real g = surface_gap(start + x * d, d, slope);
        if (g > 0.0) a = x; else b = x;
        real next = (slope != 0.0) ? x - g / slope : 0.5 * (a + b);
        // x itself is now an end of [a, b]: a converged step lands on it, so the
        // closed bracket is the test (the open one would bisect away from the root).
        if (!(next >= a && next <= b)) next = 0.5 * (a + b);
        // converged: a step below the tolerance, or below what the precision can resolve
        // of the point start + x d (steps under an ulp of it leave g unchanged)
        bool done = abs(next - x) <= max(u_root_tol, resolution + 2.0 * REAL_EPS * abs(x));
        x = next;
        if (done || g == 0.0) break;
    }
    p = start + x * d;
    depth = dent(p, dent_grad);
    return true;
}
