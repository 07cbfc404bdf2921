// Blinn-Phong: weight (n.h)^N around the mirror direction, normalised so a uniform emitter
// gives 1. Fast method: (n.h)^N ~ exp(-N theta_h^2 / 2). A direction l = r + da a + db b
// (a in the plane of incidence, b across it) tilts h by da/2 and db/(2 cos i), so the lobe
// over l is Gaussian with standard deviations 2/sqrt(N) and 2 cos(i)/sqrt(N). Mapped linearly
// onto the emitter (its Jacobian J along a and b) it is a Gaussian footprint
// J diag(2, 2 cos i) / sqrt(N) of the unit kernel: the emitter's pattern seen through it
// (exact as N -> infinity, the mirror; paraxial otherwise; the emitter's edges are not seen
// by the lobe).
uniform real u_reflection_shininess;     // Blinn-Phong exponent N

real2x2 blinn_phong_footprint(real3 p, real3 d, real3 n, real3 r, real dist) {
    real cos_i = -dot(d, n);
    real3 b = cross(n, r);
    real len_b = length(b);
    if (len_b > 1.0e-6) {
        b /= len_b;
    } else {                                  // normal incidence: any axis across r
        b = normalize(cross(r, abs(r.x) < 0.9 ? real3(1.0, 0.0, 0.0) : real3(0.0, 1.0, 0.0)));
    }
    real3 a = cross(b, r);
    real scale = 2.0 / sqrt(u_reflection_shininess);
    return emitter_jacobian(p, r, dist, scale * a, scale * cos_i * b);
}

void shade(real3 p, real3 d, real3 n, real3 r, real2 uv, real dist, float weight) {
    real2x2 footprint = blinn_phong_footprint(p, d, n, r, dist);
{$ if coherence $}
    float c = coherent_fraction(d, n);      // eq. (1): the coherent part is the mirror's
{$ endif $}
    for (int k = 0; k < PATTERNS; ++k) {
{$ if coherence $}
        pattern_sums[k] += weight * (c * emitter_radiance(uv, k) + (1.0 - c) * emitter_filtered(uv, footprint, k));
{$ else $}
        pattern_sums[k] += weight * emitter_filtered(uv, footprint, k);
{$ endif $}
    }
}
