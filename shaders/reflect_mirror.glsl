// Reflection model: ideal mirror. The pixel sees the emitter's radiance at the mirror ray's hit.
float shade(real3 d, real3 n, real3 r, real2 uv, real dist) {
    return stripes(uv.y, u_stripe_sigma);
}
