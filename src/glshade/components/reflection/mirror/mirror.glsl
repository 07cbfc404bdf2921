// Ideal mirror. The pixel sees the emitter's radiance at the mirror ray's hit{$ if coherence $};
// eq. (1) keeps the coherent fraction of it and reflects the rest diffusely (Lambertian){$ endif $}.
float shade(real3 p, real3 d, real3 n, real3 r, real2 uv, real dist) {
{$ if coherence $}
    float c = coherent_fraction(d, n);
    return c * emitter_radiance(uv) + (1.0 - c) * emitter_diffuse(p, n);
{$ else $}
    return emitter_radiance(uv);
{$ endif $}
}
