// The reflection slot's contract: the pixel value of a hit p seen along d, with unit normal
// n, mirror direction r, landing on the emitter at uv, dist mm away.
{$ if "image" in outputs $}
float shade(real3 p, real3 d, real3 n, real3 r, real2 uv, real dist);
{$ endif $}
