// Blinn-Phong: weight (n.h)^N around the mirror direction, normalised so a uniform emitter
// gives 1. Fast method: (n.h)^N ~ exp(-N theta_h^2 / 2). A direction l = r + da a + db b
// (a in the plane of incidence, b across it) tilts h by da/2 and db/(2 cos i), so the lobe
// over l is Gaussian with variances 4/N and 4 cos^2(i)/N. Mapped linearly onto the emitter
// it spreads v by sigma_v^2 = (J_a^2 4 + J_b^2 4 cos^2 i) / N, J = dv/dl: the emitter's
// pattern seen through a Gaussian of that variance (exact as N -> infinity, the mirror;
// paraxial otherwise; the emitter's edges are not seen by the lobe).
uniform real u_reflection_shininess;     // Blinn-Phong exponent N

float blinn_phong(real3 d, real3 n, real3 r, real2 uv, real dist) {
    real cos_i = -dot(d, n);
    real3 b = cross(n, r);
    real len_b = length(b);
    if (len_b > 1.0e-6) {
        b /= len_b;
    } else {                                  // normal incidence: any axis across r
        b = normalize(cross(r, abs(r.x) < 0.9 ? real3(1.0, 0.0, 0.0) : real3(0.0, 1.0, 0.0)));
    }
    real3 a = cross(b, r);
    real j_a = emitter_v_rate(r, dist, a);
    real j_b = emitter_v_rate(r, dist, b);
    real spread2 = 4.0 * (j_a * j_a + cos_i * cos_i * j_b * j_b) / u_reflection_shininess;
    return emitter_gaussian_blur(uv, spread2);
}

float shade(real3 p, real3 d, real3 n, real3 r, real2 uv, real dist) {
{$ if coherence $}
    float c = coherent_fraction(d, n);     // eq. (1): the coherent part is the mirror's
    return c * emitter_radiance(uv) + (1.0 - c) * blinn_phong(d, n, r, uv, dist);
{$ else $}
    return blinn_phong(d, n, r, uv, dist);
{$ endif $}
}
