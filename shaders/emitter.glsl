// Stripe emitter (SPEC §3). The plane is E + u e_u + v e_v with E = -De n_E, so for a
// point P (world) (E - P).n_E = -De - P.n_E and (P - E).e_u = P.e_u (E.e_u = E.e_v = 0):
// no 256 mm quantity is ever subtracted from another.
uniform real3 u_em_normal;    // n_E, unit, faces the origin
uniform real3 u_em_eu;        // e_u
uniform real3 u_em_ev;        // e_v
uniform real u_em_dist;       // De, mm
uniform real3 u_em_offset;    // (O.e_u, O.e_v, O.n_E) of the local origin O, mm
uniform real2 u_em_half;      // half extents in u and v, mm

// Hit of the ray p + t r (p local) with the emitter's front: (u, v) in mm and t.
bool emitter_hit(real3 p, real3 r, out real2 uv, out real dist) {
    real facing = dot(r, u_em_normal);
    if (!(facing < 0.0)) return false;                 // away from, or along, the emitter
    dist = (-u_em_dist - (dot(p, u_em_normal) + u_em_offset.z)) / facing;
    if (!(dist > 0.0)) return false;                   // emitter behind the point
    uv = real2(dot(p, u_em_eu) + u_em_offset.x + dist * dot(r, u_em_eu),
               dot(p, u_em_ev) + u_em_offset.y + dist * dot(r, u_em_ev));
    return abs(uv.x) <= u_em_half.x && abs(uv.y) <= u_em_half.y;   // else: curtain
}
