// Precision: fp32. Every geometric quantity is a float.
#define real float
#define real2 vec2
#define real3 vec3
#define real2x2 mat2
const real REAL_EPS = 1.1920929e-07;

real real_exp(real x) { return exp(x); }
