// The emitter's plane, facing the part. The plane is E + u e_u + v e_v with
// E = -De n_E + cu e_u + cv e_v (the rig's screen: cu = cv = 0), so for a point P
// (E - P).n_E = -De - P.n_E and (P - E).e_u = P.e_u - cu: no 256 mm quantity is ever
// subtracted from another.
uniform real3 u_emitter_normal;   // n_E, unit, faces the origin
uniform real3 u_emitter_eu;       // e_u
uniform real3 u_emitter_ev;       // e_v
uniform real u_emitter_dist;      // De: the plane's distance from the frame's origin, mm
uniform real3 u_emitter_offset;   // (O.e_u - cu, O.e_v - cv, O.n_E) of the local origin O, mm
uniform real2 u_emitter_half;     // half extents in u and v, mm

{$ if cover_glass $}
// A cover glass of thickness t and index n in front of the emitting layer (the plane above):
// its front face lies t nearer the origin; a ray refracts there and meets the layer
// t (tan i - tan r) nearer its foot than it would straight on (sin r = sin i / n).
uniform real u_emitter_glass_thickness;   // t, mm
uniform real u_emitter_glass_index;       // n
{$ endif $}
{$ if screen_sag $}

// A sagging screen (emitter.sag): its emitting layer is the plane displaced along n_E
// (towards the viewer) by w(u, v) = a u^2 + b v^2 + c u v, (a, b, c) = (bow_u / half_u^2,
// bow_v / half_v^2, twist / (half_u half_v)); a point's (u, v) is its foot on the plane. A
// cover glass follows the layer: its front face is t + w above the plane (refracted there
// as a flat glass).
uniform real3 u_emitter_sag;      // (a, b, c), 1/mm

real emitter_sag(real2 uv) {
    return uv.x * (u_emitter_sag.x * uv.x + u_emitter_sag.z * uv.y) + u_emitter_sag.y * uv.y * uv.y;
}

real2 emitter_sag_gradient(real2 uv) {
    return real2(2.0 * u_emitter_sag.x * uv.x + u_emitter_sag.z * uv.y,
                 2.0 * u_emitter_sag.y * uv.y + u_emitter_sag.z * uv.x);
}

// One Newton step on f(d) = d r.n_E - gap - w(foot + d along) (along = (r.e_u, r.e_v)):
// the ray p + d r meets the surface gap-level (the plane, or the glass's front face) + w.
real emitter_sag_step(real2 foot, real2 along, real facing, real gap, real d) {
    real2 uv = foot + d * along;
    real f = d * facing - gap - emitter_sag(uv);
    return d - f / (facing - dot(emitter_sag_gradient(uv), along));
}

// The ray's distance to the sagging surface from its plane hit d: three Newton steps (the
// oracle's glshade.components.emitter.plane.sag_distance). From the plane the error is
// |w| / |r.n_E| and each step squares it (times along.H.along / 2|f'|, H the sag's
// Hessian): a 1 mm bow on a 150 mm half size is below 1e-11 mm after two steps up to 60
// degrees from the normal; the largest sag allowed (0.1 of the half size) after three
// within 45 degrees (1e-6 mm at 60). The rounding of `real` ends it (fp32: ~1e-5 mm).
real emitter_sag_hit(real3 p, real3 r, real facing, real gap, real d) {
    real2 foot = real2(dot(p, u_emitter_eu) + u_emitter_offset.x, dot(p, u_emitter_ev) + u_emitter_offset.y);
    real2 along = real2(dot(r, u_emitter_eu), dot(r, u_emitter_ev));
    d = emitter_sag_step(foot, along, facing, gap, d);
    d = emitter_sag_step(foot, along, facing, gap, d);
    return emitter_sag_step(foot, along, facing, gap, d);
}
{$ endif $}

// Hit of the ray p + t r (p local, r unit) with the emitter's front: (u, v) in mm on the
// emitting layer and the path length to it.
bool emitter_hit(real3 p, real3 r, out real2 uv, out real dist) {
    real facing = dot(r, u_emitter_normal);
    if (!(facing < 0.0)) return false;                 // away from, or along, the emitter
    real gap = -u_emitter_dist - (dot(p, u_emitter_normal) + u_emitter_offset.z);
{$ if cover_glass $}
    dist = (gap + u_emitter_glass_thickness) / facing; // to the glass's front face
{$ if screen_sag $}
    dist = emitter_sag_hit(p, r, facing, gap + u_emitter_glass_thickness, dist);
{$ endif $}
    if (!(dist > 0.0)) return false;                   // emitter behind the point
    real2 along = real2(dot(r, u_emitter_eu), dot(r, u_emitter_ev));   // sin i along the face
    real n = u_emitter_glass_index;
    real cos_r = sqrt(max(1.0 - dot(along, along) / (n * n), 0.0));
    uv = real2(dot(p, u_emitter_eu) + u_emitter_offset.x, dot(p, u_emitter_ev) + u_emitter_offset.y)
         + dist * along + u_emitter_glass_thickness * along / (n * cos_r);
    dist += u_emitter_glass_thickness / cos_r;
{$ else $}
    dist = gap / facing;
{$ if screen_sag $}
    dist = emitter_sag_hit(p, r, facing, gap, dist);   // onto the sagging layer
{$ endif $}
    if (!(dist > 0.0)) return false;                   // emitter behind the point
    uv = real2(dot(p, u_emitter_eu) + u_emitter_offset.x + dist * dot(r, u_emitter_eu),
               dot(p, u_emitter_ev) + u_emitter_offset.y + dist * dot(r, u_emitter_ev));
{$ endif $}
    return abs(uv.x) <= u_emitter_half.x && abs(uv.y) <= u_emitter_half.y;   // else: curtain
}
{$ if shading and filtered $}

// How (u, v) moves as the ray r turns towards a, meeting a plane `to_plane` mm along r: the
// plane's Jacobian, d(uv) = to_plane (a.e - a.n_E (r.e / r.n_E)) per radian, e = e_u, e_v.
real2 emitter_rate(real3 r, real to_plane, real3 a) {
    real facing = dot(r, u_emitter_normal);
    real2 lean = real2(dot(r, u_emitter_eu), dot(r, u_emitter_ev)) / facing;
    return to_plane * (real2(dot(a, u_emitter_eu), dot(a, u_emitter_ev)) - dot(a, u_emitter_normal) * lean);
}
{$ if screen_sag $}

// On a sagging screen the hit moves on the surface's tangent plane there, normal m = n_E -
// w_u e_u - w_v e_v (unnormalised) at the hit's foot: d(uv) = to (a.e - a.m (r.e / r.m)).
real3 emitter_sag_normal(real3 p, real3 r, real to) {
    real2 uv = real2(dot(p, u_emitter_eu) + u_emitter_offset.x, dot(p, u_emitter_ev) + u_emitter_offset.y)
               + to * real2(dot(r, u_emitter_eu), dot(r, u_emitter_ev));
    real2 g = emitter_sag_gradient(uv);
    return u_emitter_normal - g.x * u_emitter_eu - g.y * u_emitter_ev;
}

real2 emitter_sag_rate(real3 r, real to, real3 a, real3 m) {
    real2 lean = real2(dot(r, u_emitter_eu), dot(r, u_emitter_ev)) / dot(r, m);
    return to * (real2(dot(a, u_emitter_eu), dot(a, u_emitter_ev)) - dot(a, m) * lean);
}
{$ endif $}
{$ if cover_glass $}

// The glass's part: the offset t x / (n cos r) inside it, x = (r.e_u, r.e_v), moves by
// t (a_x / (n c) + x (x.a_x) / (n^3 c^3)), c = cos r, as r turns towards a.
real2 glass_rate(real3 r, real3 a) {
    real2 x = real2(dot(r, u_emitter_eu), dot(r, u_emitter_ev));
    real2 ax = real2(dot(a, u_emitter_eu), dot(a, u_emitter_ev));
    real n = u_emitter_glass_index;
    real c = sqrt(max(1.0 - dot(x, x) / (n * n), 0.0));
    return u_emitter_glass_thickness * (ax / (n * c) + x * (dot(x, ax) / (n * n * n * c * c * c)));
}

{$ if screen_sag $}

real2x2 emitter_jacobian(real3 p, real3 r, real dist, real3 a1, real3 a2) {
    real2 x = real2(dot(r, u_emitter_eu), dot(r, u_emitter_ev));
    real n = u_emitter_glass_index;
    real to_face = dist - u_emitter_glass_thickness / sqrt(max(1.0 - dot(x, x) / (n * n), 0.0));
    real3 m = emitter_sag_normal(p, r, to_face);
    return real2x2(emitter_sag_rate(r, to_face, a1, m) + glass_rate(r, a1),
                   emitter_sag_rate(r, to_face, a2, m) + glass_rate(r, a2));
}
{$ else $}

real2x2 emitter_jacobian(real3 p, real3 r, real dist, real3 a1, real3 a2) {
    real gap = -u_emitter_dist - (dot(p, u_emitter_normal) + u_emitter_offset.z);
    real to_face = (gap + u_emitter_glass_thickness) / dot(r, u_emitter_normal);
    return real2x2(emitter_rate(r, to_face, a1) + glass_rate(r, a1),
                   emitter_rate(r, to_face, a2) + glass_rate(r, a2));
}
{$ endif $}
{$ elif screen_sag $}

real2x2 emitter_jacobian(real3 p, real3 r, real dist, real3 a1, real3 a2) {
    real3 m = emitter_sag_normal(p, r, dist);
    return real2x2(emitter_sag_rate(r, dist, a1, m), emitter_sag_rate(r, dist, a2, m));
}
{$ else $}

real2x2 emitter_jacobian(real3 p, real3 r, real dist, real3 a1, real3 a2) {
    return real2x2(emitter_rate(r, dist, a1), emitter_rate(r, dist, a2));
}
{$ endif $}
{$ endif $}
{$ if shading and diffuse $}

// The emitter rectangle's form factor seen from p with unit normal n: (1/pi) times its
// projected solid angle above the tangent plane, by Lambert's polygon formula on the
// rectangle clipped to the plane (Sutherland-Hodgman).
float emitter_form_factor(real3 p, real3 n) {
    vec3 corner[4];
    vec3 centre = vec3(-u_emitter_dist * u_emitter_normal - u_emitter_offset.x * u_emitter_eu - u_emitter_offset.y * u_emitter_ev
                       - u_emitter_offset.z * u_emitter_normal - p);                  // emitter centre - p, mm
    vec3 eu = vec3(u_emitter_eu) * float(u_emitter_half.x);
    vec3 ev = vec3(u_emitter_ev) * float(u_emitter_half.y);
    corner[0] = centre - eu - ev;
    corner[1] = centre + eu - ev;
    corner[2] = centre + eu + ev;
    corner[3] = centre - eu + ev;
    vec3 nf = vec3(n);
    vec3 poly[5];
    int count = 0;
    for (int i = 0; i < 4; ++i) {
        vec3 a = corner[i];
        vec3 b = corner[(i + 1) % 4];
        float da = dot(nf, a);
        float db = dot(nf, b);
        if (da >= 0.0) poly[count++] = a;
        if ((da >= 0.0) != (db >= 0.0)) poly[count++] = a + (b - a) * (da / (da - db));
    }
    float sum = 0.0;
    for (int i = 0; i < count; ++i) {
        vec3 a = normalize(poly[i]);
        vec3 b = normalize(poly[(i + 1) % count]);
        vec3 c = cross(a, b);
        float len = length(c);
        if (len > 0.0) sum += acos(clamp(dot(a, b), -1.0, 1.0)) * dot(nf, c) / len;
    }
    return abs(sum) / 6.2831853;
}
{$ endif $}
