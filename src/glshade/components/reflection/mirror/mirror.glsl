// Ideal mirror. The pixel sees each pattern's radiance at the mirror ray's landing point{$ if coherence $};
// eq. (1) keeps the coherent fraction of it and reflects the rest diffusely (Lambertian){$ endif $}.
void shade(real3 p, real3 d, real3 n, real3 r, real2 uv, real dist, float weight) {
{$ if coherence $}
    float c = coherent_fraction(d, n);
{$ endif $}
    for (int k = 0; k < PATTERNS; ++k) {
{$ if coherence $}
        pattern_sums[k] += weight * (c * emitter_radiance(uv, k) + (1.0 - c) * emitter_diffuse(p, n, k));
{$ else $}
        pattern_sums[k] += weight * emitter_radiance(uv, k);
{$ endif $}
    }
}
