// Root finding along a ray, shared by the dent's first-hit solve and the free-form
// surfaces' march. A caller declares, along start + s d (s in [0, span]):
//   real g, slope;            // the gap at s and its derivative along d (g > 0: above)
//   real s, a, b, g_a, g_b;   // position; bracket [a, b] and the gap at its ends
//   bool crossed, converged;
//   real k2, resolution;      // bound on |g''| along the ray; the precision's step floor
// and calls the macros with its gap function (a call block whose argument is the point).

// The safe step: with K bounding |g''| along the ray, g(s + h) >= g + g' h - K h^2 / 2,
// which stays positive for every h below h_safe = 2 g / (sqrt(g'^2 + 2 K g) - g').
// Approaching a transversal root h_safe ~ g / |g'| (quadratic convergence from above,
// like Newton, but never overshooting); near a ray that skims a bump without crossing it
// the steps stay ~ sqrt(2 g / K) and grow again past the closest approach.
real safe_step(real g, real slope, real k2) {
    return 2.0 * g / (sqrt(slope * slope + 2.0 * k2 * g) - slope);
}

{# The march: at most `steps` safe steps; stops `converged` where a step falls below the
   resolution (the root, reached from above) or `crossed` where a step lands at or below
   the surface (the root is then bracketed in [a, b]). `nan_crosses`: a NaN gap counts as
   below (a free-form surface that does not exist there). #}
{$ macro safe_march(steps, tol, nan_crosses) $}
    for (int i = 0; i < {{ steps }} && !crossed && !converged && s < span; ++i) {
        real h = safe_step(g, slope, k2);
        if (!(h >= 0.0)) h = span - s;    // K = 0 and g' >= 0: g cannot fall to 0 here
        h = min(h, span - s);
        if (h <= max({{ tol }}, resolution + 2.0 * REAL_EPS * s)) {
            converged = true;             // within the resolution of the root, from above
            break;
        }
        a = s;
        g_a = g;
        s += h;
        g = {{ caller("start + s * d") }};
{$ if nan_crosses $}
        if (!(g > 0.0)) {
{$ else $}
        if (g <= 0.0) {
{$ endif $}
            crossed = true;
            b = s;
            g_b = g;
        }
    }
{$ endmacro $}

{# Newton's method safeguarded by bisection: polishes x inside the bracket [a, b] (g > 0
   at a, g <= 0 at b) in at most `iterations` steps, until a step is below `tol` or the
   resolution. #}
{$ macro newton_bisection(iterations, tol) $}
    for (int it = 0; it < {{ iterations }} && b > a; ++it) {
        real gx = {{ caller("start + x * d") }};
        if (gx > 0.0) a = x; else b = x;
        real next = (slope != 0.0) ? x - gx / slope : 0.5 * (a + b);
        // x itself is now an end of [a, b]: a converged step lands on it, so the
        // closed bracket is the test (the open one would bisect away from the root).
        if (!(next >= a && next <= b)) next = 0.5 * (a + b);
        bool done = abs(next - x) <= max({{ tol }}, resolution + 2.0 * REAL_EPS * abs(x));
        x = next;
        if (done || gx == 0.0) break;
    }
{$ endmacro $}
