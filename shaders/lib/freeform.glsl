// The first crossing from above of a free-form surface (a formula or a height map): the
// surface file defines freeform_gap(p, d, shift, slope) = y - f - shift at p and its
// derivative along d. The march is the dent solve's (lib/march.glsl): its steps never
// pass a root; a step landing on g <= 0 brackets the first one, which Newton safeguarded
// by bisection polishes. A march that runs out of steps, or leaves the stretch above the
// surface, reports no crossing: a missing pixel, never a wrong one.
{$ import "lib/march.glsl" as march $}
real freeform_gap(real3 p, real3 d, real shift, out real slope);  // defined by the surface file

uniform int u_surface_march_steps;  // most steps of the march
uniform real u_surface_march_tol;   // mm along the ray

// s_hit in [0, span] along start + s d; curvature: bound on |f''| along horizontal unit
// directions (1/mm). False when g(start) <= 0 (already below) or no crossing was found.
bool freeform_march(real3 start, real3 d, real shift, real span, real curvature, out real s_hit) {
    real k2 = dot(d.xz, d.xz) * curvature;
    real resolution = 2.0 * REAL_EPS * max(max(abs(start.x), abs(start.y)), abs(start.z));
    real slope;
    real g = freeform_gap(start, d, shift, slope);
    s_hit = 0.0;
    if (!(g > 0.0)) return false;
    real s = 0.0, a = 0.0, b = 0.0, g_a = g, g_b = g;
    bool crossed = false;
    bool converged = false;
{$ call(point) march.safe_march("u_surface_march_steps", "u_surface_march_tol", true) $}freeform_gap({{ point }}, d, shift, slope){$ endcall $}
    if (converged) {
        s_hit = s;                    // within the resolution of the root, from above
        return true;
    }
    if (!crossed) return false;
    real x = (g_b < 0.0) ? a + (b - a) * g_a / (g_a - g_b) : 0.5 * (a + b);
{# 64: surface/freeform.py's POLISH_ITERATIONS, which the renderer's loop count uses #}
{$ call(point) march.newton_bisection("64", "u_surface_march_tol") $}freeform_gap({{ point }}, d, shift, slope){$ endcall $}
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
