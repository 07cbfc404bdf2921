// The emitter's plane, facing the origin in the camera's mirror position. The plane is
// E + u e_u + v e_v with E = -De n_E, so for a point P (world) (E - P).n_E = -De - P.n_E and
// (P - E).e_u = P.e_u (E.e_u = E.e_v = 0): no 256 mm quantity is ever subtracted from another.
uniform real3 u_emitter_normal;   // n_E, unit, faces the origin
uniform real3 u_emitter_eu;       // e_u
uniform real3 u_emitter_ev;       // e_v
uniform real u_emitter_dist;      // De, mm
uniform real3 u_emitter_offset;   // (O.e_u, O.e_v, O.n_E) of the local origin O, mm
uniform real2 u_emitter_half;     // half extents in u and v, mm

// Hit of the ray p + t r (p local) with the emitter's front: (u, v) in mm and t.
bool emitter_hit(real3 p, real3 r, out real2 uv, out real dist) {
    real facing = dot(r, u_emitter_normal);
    if (!(facing < 0.0)) return false;                 // away from, or along, the emitter
    dist = (-u_emitter_dist - (dot(p, u_emitter_normal) + u_emitter_offset.z)) / facing;
    if (!(dist > 0.0)) return false;                   // emitter behind the point
    uv = real2(dot(p, u_emitter_eu) + u_emitter_offset.x + dist * dot(r, u_emitter_eu),
               dot(p, u_emitter_ev) + u_emitter_offset.y + dist * dot(r, u_emitter_ev));
    return abs(uv.x) <= u_emitter_half.x && abs(uv.y) <= u_emitter_half.y;   // else: curtain
}
{$ if "image" in outputs and blur != "none" $}

// How fast v moves when the ray r (landing dist mm away) turns towards a: the plane's
// Jacobian, dv = dist (a.e_v - a.n_E (r.e_v / r.n_E)) per radian.
real emitter_v_rate(real3 r, real dist, real3 a) {
    real lean = dot(r, u_emitter_ev) / dot(r, u_emitter_normal);
    return dist * (dot(a, u_emitter_ev) - dot(a, u_emitter_normal) * lean);
}
{$ endif $}
