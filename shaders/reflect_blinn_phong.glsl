// Reflection model: Blinn-Phong, weight (n.h)^N around the mirror direction, normalised
// so a uniform emitter gives 1 (SPEC §5).
// Fast method: (n.h)^N ~ exp(-N theta_h^2 / 2). A direction l = r + da a + db b (a in the
// plane of incidence, b across it) tilts h by da/2 and db/(2 cos i), so the lobe over l
// is Gaussian with variances 4/N and 4 cos^2(i)/N. Mapped linearly onto the emitter it
// spreads v by sigma_v^2 = (J_a^2 4 + J_b^2 4 cos^2 i) / N, J = dv/dl. A Gaussian stripe
// convolved with a Gaussian lobe stays Gaussian: width sqrt(s^2 + sigma_v^2), peak
// s / sqrt(s^2 + sigma_v^2). Exact as N -> infinity (the mirror), paraxial otherwise;
// the emitter's edges are not seen by the lobe.
uniform real u_shininess;     // Blinn-Phong exponent N

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
    real lean = dot(r, u_em_ev) / dot(r, u_em_normal);
    real j_a = dist * (dot(a, u_em_ev) - dot(a, u_em_normal) * lean);
    real j_b = dist * (dot(b, u_em_ev) - dot(b, u_em_normal) * lean);
    real spread2 = 4.0 * (j_a * j_a + cos_i * cos_i * j_b * j_b) / u_shininess;
    real width = sqrt(u_stripe_sigma * u_stripe_sigma + spread2);
    return float(u_stripe_sigma / width) * stripes(uv.y, width);
}

float shade(real3 p, real3 d, real3 n, real3 r, real2 uv, real dist) {
{$ if coherence $}
    float c = coherent_fraction(d, n);     // eq. (1): the coherent part is the mirror's
    return c * stripes(uv.y, u_stripe_sigma) + (1.0 - c) * blinn_phong(d, n, r, uv, dist);
{$ else $}
    return blinn_phong(d, n, r, uv, dist);
{$ endif $}
}
