// The defect slot's contract: the defect D(x, z) on the base surface and the first hit it
// needs (bracketed between the base surface shifted by D's extremes).
bool surface_hit(real3 o, real3 d, real tmin, out real3 p, out real depth, out real2 dent_grad);
{$ if "iterations" in outputs $}
int g_evaluations;                           // evaluations of the gap by the last surface_hit
{$ endif $}
