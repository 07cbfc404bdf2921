// The first crossing from above of a free-form surface (a formula or a height map): the
// surface file defines freeform_gap(p, d, shift, slope) = y - f - shift at p and its
// derivative along d. The march is the dent solve's (surface_hit_dent.glsl): with K
// bounding |g''| along the ray, a step h = 2 g / (sqrt(g'^2 + 2 K g) - g') never passes a
// root; a step landing on g <= 0 brackets the first one, which Newton safeguarded by
// bisection polishes. A march that runs out of steps, or leaves the stretch above the
// surface, reports no crossing: a missing pixel, never a wrong one.
real freeform_gap(real3 p, real3 d, real shift, out real slope);  // defined by the surface file

uniform int u_freeform_steps;      // most steps of the march
uniform real u_freeform_tol;       // mm along the ray

// s_hit in [0, span] along start + s d; curvature: bound on |f''| along horizontal unit
// directions (1/mm). False when g(start) <= 0 (already below) or no crossing was found.
bool freeform_march(real3 start, real3 d, real shift, real span, real curvature, out real s_hit) {
    real k2 = dot(d.xz, d.xz) * curvature;
    real resolution = 2.0 * REAL_EPS * max(max(abs(start.x), abs(start.y)), abs(start.z));
    real slope;
    real g = freeform_gap(start, d, shift, slope);
    s_hit = 0.0;
    if (!(g > 0.0)) return false;
    real s = 0.0, lo = 0.0, hi = 0.0, g_lo = g, g_hi = g;
    bool crossed = false;
    for (int i = 0; i < u_freeform_steps && !crossed && s < span; ++i) {
        real h = 2.0 * g / (sqrt(slope * slope + 2.0 * k2 * g) - slope);
        if (!(h >= 0.0)) h = span - s;  // K = 0 and g' >= 0: g cannot fall to 0 here
        h = min(h, span - s);
        if (h <= max(u_freeform_tol, resolution + 2.0 * REAL_EPS * s)) {
            s_hit = s;                    // within the resolution of the root, from above
            return true;
        }
        lo = s;
        g_lo = g;
        s += h;
        g = freeform_gap(start + s * d, d, shift, slope);
        if (!(g > 0.0)) {
            crossed = true;
            hi = s;
            g_hi = g;
        }
    }
    if (!crossed) return false;
    real x = (g_hi < 0.0) ? lo + (hi - lo) * g_lo / (g_lo - g_hi) : 0.5 * (lo + hi);
    for (int it = 0; it < 64 && hi > lo; ++it) {
        real gx = freeform_gap(start + x * d, d, shift, slope);
        if (gx > 0.0) lo = x; else hi = x;
        real next = (slope != 0.0) ? x - gx / slope : 0.5 * (lo + hi);
        if (!(next >= lo && next <= hi)) next = 0.5 * (lo + hi);
        bool done = abs(next - x) <= max(u_freeform_tol, resolution + 2.0 * REAL_EPS * abs(x));
        x = next;
        if (done || gx == 0.0) break;
    }
    s_hit = x;
    return true;
}

// The ray's stretch [enter, leave] inside the slab bottom <= y <= top (t > tmin).
bool freeform_slab(real3 o, real3 d, real top, real bottom, real tmin, out real enter, out real leave) {
    if (d.y < 0.0) {
        enter = (top - o.y) / d.y;
        leave = (bottom - o.y) / d.y;
    } else if (d.y > 0.0) {
        enter = (bottom - o.y) / d.y;
        leave = (top - o.y) / d.y;
    } else {
        enter = tmin;
        leave = (o.y > top || o.y < bottom) ? tmin : tmin + 1.0e4;
    }
    enter = max(enter, tmin);
    return enter < leave;
}
