// Base surface: a height map, bicubic Catmull-Rom between its samples (C1: continuous
// normals), beyond it nothing (curtain) or the plane y = 0 (flat). The samples are a
// float texture read texel by texel; the spline and its gradient are exact in real.
// Unmeasured samples were filled (harmonically) for the first-hit solve; with holes, the
// cells whose spline reads one are flagged, and a hit there is a miss (base_measured).
uniform sampler2D t_surface_heights;       // texel (column, row): heights[row, column] in mm as float pairs hi + lo (r, g); b: 1 where cell [row, column] is a hole
uniform real2 u_surface_corner;        // local (x, z) of sample [row 0, column 0], mm
uniform real2 u_surface_spacing;       // (dx, dz), mm
uniform ivec2 u_surface_size;          // (columns, rows)
uniform real u_surface_lo;             // the spline lies in [lo, hi] (mm; flat: 0 included)
uniform real u_surface_hi;
uniform real u_surface_curvature;      // bound on |f''| along horizontal unit directions (1/mm)

vec2 map_pair(int column, int row) {
    return texelFetch(t_surface_heights, ivec2(clamp(column, 0, u_surface_size.x - 1), clamp(row, 0, u_surface_size.y - 1)), 0).rg;
}

// Catmull-Rom weights of the 4 taps at t in [0, 1], and their derivatives.
void spline_weights(real t, out real w[4], out real dw[4]) {
    real t2 = t * t, t3 = t2 * t;
    w[0] = 0.5 * (-t3 + 2.0 * t2 - t);
    w[1] = 0.5 * (3.0 * t3 - 5.0 * t2 + 2.0);
    w[2] = 0.5 * (-3.0 * t3 + 4.0 * t2 + t);
    w[3] = 0.5 * (t3 - t2);
    dw[0] = 0.5 * (-3.0 * t2 + 4.0 * t - 1.0);
    dw[1] = 0.5 * (9.0 * t2 - 10.0 * t);
    dw[2] = 0.5 * (-9.0 * t2 + 8.0 * t + 1.0);
    dw[3] = 0.5 * (3.0 * t2 - 2.0 * t);
}

bool map_inside(real2 q) {
    real2 g = (q - u_surface_corner) / u_surface_spacing;
    return g.x >= 0.0 && g.y >= 0.0 && g.x <= real(u_surface_size.x - 1) && g.y <= real(u_surface_size.y - 1);
}

// The spline at local (x, z) = q and its gradient (clamped to the map's edge).
real map_height(real2 q, out real2 grad) {
    real2 top = real2(u_surface_size - ivec2(1));
    real2 g = clamp((q - u_surface_corner) / u_surface_spacing, real2(0.0), top);
    real2 cell = clamp(floor(g), real2(0.0), top - 1.0);
    real wu[4], dwu[4], wv[4], dwv[4];
    spline_weights(g.x - cell.x, wu, dwu);
    spline_weights(g.y - cell.y, wv, dwv);
    int c0 = int(cell.x) - 1, r0 = int(cell.y) - 1;
    // Taps relative to the cell's first sample (hi - hi and lo - lo: exact differences), so
    // fp32 slopes are not the rounding of millimetre heights divided by the spacing.
    vec2 ref = map_pair(c0 + 1, r0 + 1);
    real f = 0.0, fu = 0.0, fv = 0.0;
    for (int b = 0; b < 4; ++b) {
        real row = 0.0, row_u = 0.0;
        for (int a = 0; a < 4; ++a) {
            vec2 pair = map_pair(c0 + a, r0 + b);
            real h = real(pair.x - ref.x) + real(pair.y - ref.y);
            row += wu[a] * h;
            row_u += dwu[a] * h;
        }
        f += wv[b] * row;
        fu += wv[b] * row_u;
        fv += dwv[b] * row;
    }
    grad = real2(fu, fv) / u_surface_spacing;
    return (real(ref.x) + real(ref.y)) + f;   // the weights sum to 1
}

{$ if surface_holes is defined and surface_holes $}
// False where the hit's cell (found as map_height finds it) reads an unmeasured sample.
bool base_measured(real3 p) {
{$ if heightmap_outside == "flat" $}
    if (!map_inside(p.xz)) return true;
{$ endif $}
    real2 top = real2(u_surface_size - ivec2(1));
    real2 g = clamp((p.xz - u_surface_corner) / u_surface_spacing, real2(0.0), top);
    ivec2 cell = ivec2(clamp(floor(g), real2(0.0), top - 1.0));
    return texelFetch(t_surface_heights, cell, 0).b < 0.5;
}
{$ endif $}

// f and its gradient where the surface is: the spline over the map, the plane beyond it.
real surface_height(real2 q, out real2 grad) {
{$ if heightmap_outside == "flat" $}
    if (!map_inside(q)) {
        grad = real2(0.0);
        return 0.0;
    }
{$ endif $}
    return map_height(q, grad);
}

real freeform_gap(real3 p, real3 d, real shift, out real slope) {
    real2 grad;
    real f = surface_height(p.xz, grad);
    slope = d.y - dot(grad, d.xz);
    return p.y - f - shift;
}

// The ray's stretch over the map's rectangle (t > tmin): false when it never is.
bool map_stretch(real3 o, real3 d, real tmin, out real enter, out real leave) {
    real2 lo = u_surface_corner, hi = u_surface_corner + real2(u_surface_size - ivec2(1)) * u_surface_spacing;
    enter = tmin;
    leave = 1.0e30;
    for (int k = 0; k < 2; ++k) {
        real ok = (k == 0) ? o.x : o.z, dk = (k == 0) ? d.x : d.z;
        real a = lo[k], b = hi[k];
        if (dk == 0.0) {
            if (ok < a || ok > b) return false;
        } else {
            real t1 = (a - ok) / dk, t2 = (b - ok) / dk;
            enter = max(enter, min(t1, t2));
            leave = min(leave, max(t1, t2));
        }
    }
    return enter < leave;
}

// First crossing from above of y = f + shift along o + t d, t > tmin (lib/freeform.glsl).
bool base_hit(real3 o, real3 d, real shift, real tmin, out real t, out real t_far) {
    real enter, leave, slab_in, slab_out, s;
    t_far = 1.0e30;
    bool found = false;
    if (map_stretch(o, d, tmin, enter, leave)
        && freeform_slab(o, d, u_surface_hi + shift, u_surface_lo + shift, tmin, slab_in, slab_out)) {
        real a = max(enter, slab_in), b = min(leave, slab_out);
        t_far = b;
        if (a < b && freeform_march(o + a * d, d, shift, b - a, u_surface_curvature, s)) {
            t = a + s;
            found = true;
        }
    }
{$ if heightmap_outside == "flat" $}
    // beyond the map: the plane y = shift, where the ray meets it outside the rectangle
    if (d.y < 0.0) {
        real t_plane = (shift - o.y) / d.y;
        if (t_plane > tmin && !map_inside((o + t_plane * d).xz) && (!found || t_plane < t)) {
            t = t_plane;
            found = true;
        }
    }
    t_far = 1.0e30;
{$ endif $}
    return found;
}

real base_height(real3 p) {
    real2 grad;
    return surface_height(p.xz, grad);
}
real base_curvature(real3 p) { return u_surface_curvature; }
real2 base_slope(real3 p) {
    real2 grad;
    surface_height(p.xz, grad);
    return grad;
}

// Unnormalised normal of y = f + D at p, given D and grad D = (D_x, D_z).
real3 base_normal(real3 p, real depth, real2 dent_grad) {
    real2 slope = base_slope(p) + dent_grad;
    return real3(-slope.x, 1.0, -slope.y);
}
