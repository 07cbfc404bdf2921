// Precision: fp64 (GL_ARB_gpu_shader_fp64, core since GL 4.0): the GPU-side reference.
#define real double
#define real2 dvec2
#define real3 dvec3
#define real2x2 dmat2
const real REAL_EPS = 2.220446049250313e-16lf;

// GLSL has no double exp(); this one is accurate to a few ulp for x <= 0.
// x = k ln2 + r with |r| <= ln2/2 (ln2 split in two so k ln2 is exact to 1e-26),
// then a degree-13 Taylor polynomial: remainder r^14/14! < 5e-18 relative.
real real_exp(real x) {
    if (x < -708.0lf) return 0.0lf;
    const real LN2_HI = 6.93147180369123816490e-01lf;
    const real LN2_LO = 1.90821492927058770002e-10lf;
    real k = floor(x / (LN2_HI + LN2_LO) + 0.5lf);
    real r = (x - k * LN2_HI) - k * LN2_LO;
    real p = 1.0lf / 6227020800.0lf;  // 1/13!
    p = p * r + 1.0lf / 479001600.0lf;
    p = p * r + 1.0lf / 39916800.0lf;
    p = p * r + 1.0lf / 3628800.0lf;
    p = p * r + 1.0lf / 362880.0lf;
    p = p * r + 1.0lf / 40320.0lf;
    p = p * r + 1.0lf / 5040.0lf;
    p = p * r + 1.0lf / 720.0lf;
    p = p * r + 1.0lf / 120.0lf;
    p = p * r + 1.0lf / 24.0lf;
    p = p * r + 1.0lf / 6.0lf;
    p = p * r + 0.5lf;
    p = p * r + 1.0lf;
    p = p * r + 1.0lf;
    return ldexp(p, int(k));
}
