// Microfacet reflection (Cook-Torrance), {{ lobe }} slopes of roughness alpha, height-
// correlated Smith shadowing. Over the half vector h = normalise(n + x e1 + y e2) (slopes
// (x, y); e1 in the plane of incidence) the pixel is
//   integral of L(v(l)) P22(x, y) W dx dy,  l = 2 (wo.h) h - wo,  W = G2 (wo.h) / ((n.wo)(n.h)),
// P22 the slope density ({{ lobe }}). Method: {{ lobe_method }}.
uniform real u_reflection_alpha;          // roughness alpha (rms slope x sqrt 2 for Beckmann)
{$ if lobe_method != "closed" $}
uniform int u_reflection_lobe_samples;   // slope samples per ray
{$ endif $}

// Smith's Lambda for a direction at cos theta = c to the normal.
float smith_lambda(float c) {
    float c2 = max(c * c, 1.0e-12);
    float tan2 = max(1.0 - c2, 0.0) / c2;
    float alpha = float(u_reflection_alpha);
{$ if lobe == "beckmann" $}
    float a = 1.0 / max(alpha * sqrt(tan2), 1.0e-12);
    return a >= 1.6 ? 0.0 : (1.0 - 1.259 * a + 0.396 * a * a) / (3.535 * a + 2.181 * a * a);
{$ else $}
    return 0.5 * (sqrt(1.0 + alpha * alpha * tan2) - 1.0);
{$ endif $}
}

// The tangent frame of the lobe: e1 towards wo (in the plane of incidence), e2 = n x e1.
void lobe_frame(real3 n, real3 wo, out real3 e1, out real3 e2) {
    e1 = wo - dot(wo, n) * n;
    real len = length(e1);
    if (len > 1.0e-6) {
        e1 /= len;
    } else {                                  // normal incidence: any axis across n
        e1 = normalize(cross(n, abs(n.x) < 0.9 ? real3(1.0, 0.0, 0.0) : real3(0.0, 1.0, 0.0)));
    }
    e2 = cross(n, e1);
}

{$ if lobe_method == "closed" $}
// Closed form: v(l) linearised about the mirror ray, l = r + x dl/dx + y dl/dy for slopes
// (x, y), so the lobe maps onto the emitter as the footprint J (dl/dx, dl/dy) times the
// slopes' scale: the unit kernel ({{ kernel }}) at alpha / sqrt 2 (Beckmann: Gaussian slopes
// of that standard deviation) or alpha (GGX), through which the emitter's pattern is seen;
// shadowing taken at the mirror direction.
{$ if lobe == "beckmann" $}
const float SLOPE_SCALE = 0.70710678;         // Beckmann's slopes: std alpha / sqrt 2 each
{$ else $}
const float SLOPE_SCALE = 1.0;                // GGX's slope density at alpha = 1 is the kernel's
{$ endif $}

void shade(real3 p, real3 d, real3 n, real3 r, real2 uv, real dist, float weight) {
    real3 wo = -d;
    real3 e1, e2;
    lobe_frame(n, wo, e1, e2);
    real cos_o = dot(wo, n);
    real scale = real(SLOPE_SCALE) * u_reflection_alpha;
    real3 dl_x = 2.0 * dot(wo, e1) * n + 2.0 * cos_o * e1;   // dl/dx at the mirror direction
    real3 dl_y = 2.0 * cos_o * e2;
    real2x2 footprint = emitter_jacobian(p, r, dist, scale * dl_x, scale * dl_y);
    float shadowing = 1.0 / (1.0 + 2.0 * smith_lambda(float(cos_o)));
{$ if coherence $}
    float c = coherent_fraction(d, n);
{$ endif $}
    for (int k = 0; k < PATTERNS; ++k) {
        float lobe = shadowing * emitter_filtered(uv, footprint, k);
{$ if coherence $}
        pattern_sums[k] += weight * (c * emitter_radiance(uv, k) + (1.0 - c) * lobe);
{$ else $}
        pattern_sums[k] += weight * lobe;
{$ endif $}
    }
}
{$ else $}
// Importance sampling of the slope density: u_reflection_lobe_samples points of a Fibonacci
// lattice in the unit square{$ if lobe_method == "sampling" $}, shifted per pixel by a hash
// (randomised quasi-Monte Carlo: unbiased, with noise){$ endif $}, mapped to slopes through
// the kernel's inverse CDF of the radius (lib/kernels.glsl) and a uniform angle. Each sampled
// direction lands on the emitter once and is shaded for every pattern.
void shade(real3 p, real3 d, real3 n, real3 r, real2 uv, real dist, float weight) {
    real3 wo = -d;
    real3 e1, e2;
    lobe_frame(n, wo, e1, e2);
    float cos_o = float(dot(wo, n));
    float lambda_o = smith_lambda(cos_o);
{$ if lobe == "beckmann" $}
    float scale = 0.70710678 * float(u_reflection_alpha);   // slopes: std alpha / sqrt 2 each
{$ else $}
    float scale = float(u_reflection_alpha);
{$ endif $}
    int count = u_reflection_lobe_samples;
{$ if lobe_method == "sampling" $}
    uvec2 key = uvec2(gl_FragCoord.xy) * uvec2(1664525u, 22695477u);
    uint h = (key.x ^ (key.y >> 7u) ^ 0x9e3779b9u) * 2654435761u;
    vec2 shift = vec2(float(h & 0xffffu), float(h >> 16u)) / 65536.0;
{$ else $}
    vec2 shift = vec2(0.0);
{$ endif $}
{$ if coherence $}
    float c = coherent_fraction(d, n);
    for (int k = 0; k < PATTERNS; ++k) pattern_sums[k] += weight * c * emitter_radiance(uv, k);
    float lobe_weight = weight * (1.0 - c) / float(count);
{$ else $}
    float lobe_weight = weight / float(count);
{$ endif $}
    for (int i = 0; i < count; ++i) {
        vec2 slope = scale * kernel_point(i, count, shift);
        real3 h = normalize(n + real(slope.x) * e1 + real(slope.y) * e2);
        real wo_h = dot(wo, h);
        if (!(wo_h > 0.0)) continue;
        real3 l = 2.0 * wo_h * h - wo;
        float cos_l = float(dot(l, n));
        if (!(cos_l > 0.0)) continue;
        real2 luv;
        real ldist;
        if (!emitter_hit(p, l, luv, ldist)) continue;
        float g2 = 1.0 / (1.0 + lambda_o + smith_lambda(cos_l));
        float w = lobe_weight * g2 * float(wo_h) / (cos_o * float(dot(n, h)));
        for (int k = 0; k < PATTERNS; ++k) pattern_sums[k] += w * emitter_radiance(luv, k);
    }
}
{$ endif $}
