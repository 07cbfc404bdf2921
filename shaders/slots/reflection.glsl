// The reflection slot's contract: a hit p seen along d, with unit normal n, mirror direction
// r, landing on the emitter at uv, dist mm away. For each pattern k the program shades
// (0 to PATTERNS - 1), shade() adds weight times the pixel value the surface gives it to
// pattern_sums[k]; weight is what the surface reflects (Fresnel), and the one path serves
// the image (one pattern) and a stack of emitter frames alike.
{$ if shading $}
void shade(real3 p, real3 d, real3 n, real3 r, real2 uv, real dist, float weight);
{$ endif $}
