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
// Closed form along v: v(l) linearised about the mirror ray, v = v0 + jx x + jy y, so the
// lobe spreads v by the slope density's marginal along (jx, jy), scaled by |j|:
{$ if lobe == "beckmann" $}
// a Gaussian of std |j| alpha / sqrt 2, through which the emitter's pattern is seen.
float lobe_stripes(real2 uv, float spread) {
    float s = spread * float(u_reflection_alpha) * 0.70710678;
    return emitter_gaussian_blur(uv, real(s * s));
}
{$ else $}
// GGX: alpha^2 / (2 (alpha^2 + s^2)^(3/2)), the emitter's pattern seen through it.
float lobe_stripes(real2 uv, float spread) {
    return emitter_ggx_blur(uv, spread * float(u_reflection_alpha));
}
{$ endif $}

float lobe(real3 p, real3 d, real3 n, real3 r, real2 uv, real dist) {
    real3 wo = -d;
    real3 e1, e2;
    lobe_frame(n, wo, e1, e2);
    real cos_o = dot(wo, n);
    real3 dl_x = 2.0 * dot(wo, e1) * n + 2.0 * cos_o * e1;   // dl/dx at the mirror direction
    real3 dl_y = 2.0 * cos_o * e2;
    real jx = emitter_v_rate(r, dist, dl_x);
    real jy = emitter_v_rate(r, dist, dl_y);
    float shadowing = 1.0 / (1.0 + 2.0 * smith_lambda(float(cos_o)));
    return shadowing * lobe_stripes(uv, float(sqrt(jx * jx + jy * jy)));
}
{$ else $}
// Importance sampling of the slope density: u_reflection_lobe_samples points of a Fibonacci lattice
// in the unit square{$ if lobe_method == "sampling" $}, shifted per pixel by a hash (randomised
// quasi-Monte Carlo: unbiased, with noise){$ endif $}, mapped to slopes by the inverse CDF
// of the radius ({{ lobe }}) and a uniform angle.
float lobe(real3 p, real3 d, real3 n, real3 r, real2 uv, real dist) {
    real3 wo = -d;
    real3 e1, e2;
    lobe_frame(n, wo, e1, e2);
    float cos_o = float(dot(wo, n));
    float lambda_o = smith_lambda(cos_o);
    float alpha = float(u_reflection_alpha);
    float inv_count = 1.0 / float(u_reflection_lobe_samples);
{$ if lobe_method == "sampling" $}
    uvec2 key = uvec2(gl_FragCoord.xy) * uvec2(1664525u, 22695477u);
    uint h = (key.x ^ (key.y >> 7u) ^ 0x9e3779b9u) * 2654435761u;
    vec2 shift = vec2(float(h & 0xffffu), float(h >> 16u)) / 65536.0;
{$ else $}
    vec2 shift = vec2(0.0);
{$ endif $}
    float total = 0.0;
    for (int k = 0; k < u_reflection_lobe_samples; ++k) {
        float u1 = fract((float(k) + 0.5) * inv_count + shift.x);
        float u2 = fract(float(k) * 0.61803399 + shift.y);
{$ if lobe == "beckmann" $}
        float radius = alpha * sqrt(-log(1.0 - u1));
{$ else $}
        float radius = alpha * sqrt(u1 / (1.0 - u1));
{$ endif $}
        float phi = 6.2831853 * u2;
        real3 h = normalize(n + real(radius * cos(phi)) * e1 + real(radius * sin(phi)) * e2);
        real wo_h = dot(wo, h);
        if (!(wo_h > 0.0)) continue;
        real3 l = 2.0 * wo_h * h - wo;
        float cos_l = float(dot(l, n));
        if (!(cos_l > 0.0)) continue;
        real2 luv;
        real ldist;
        if (!emitter_hit(p, l, luv, ldist)) continue;
        float g2 = 1.0 / (1.0 + lambda_o + smith_lambda(cos_l));
        total += emitter_radiance(luv) * g2 * float(wo_h) / (cos_o * float(dot(n, h)));
    }
    return total * inv_count;
}
{$ endif $}

float shade(real3 p, real3 d, real3 n, real3 r, real2 uv, real dist) {
{$ if coherence $}
    float c = coherent_fraction(d, n);
    return c * emitter_radiance(uv) + (1.0 - c) * lobe(p, d, n, r, uv, dist);
{$ else $}
    return lobe(p, d, n, r, uv, dist);
{$ endif $}
}
