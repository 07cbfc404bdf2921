// The render slot's contract (the program's preamble): the arithmetic of every geometric
// quantity. Its component defines the types real, real2, real3 and real2x2 (one precision
// for all), the constant REAL_EPS (their machine epsilon) and:
real real_exp(real x);                       // exp in that precision
