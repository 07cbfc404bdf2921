// The surface slot's contract: the base surface y = f(x, z) in the local frame (world minus
// the dent centre), mm.
// First crossing from above of y = f + shift along o + t d with t > tmin; t_far: where the
// ray is back above the shifted surface (1e30: never).
bool base_hit(real3 o, real3 d, real shift, real tmin, out real t, out real t_far);
real base_height(real3 p);                   // f at p
real base_curvature(real3 p);                // a bound on |f''| along horizontal unit directions, 1/mm
real2 base_slope(real3 p);                   // (f_x, f_z) at p
real3 base_normal(real3 p, real depth, real2 dent_grad);   // unnormalised normal of f + D
{$ if surface_holes is defined and surface_holes $}
bool base_measured(real3 p);                 // false where the surface has no data (a hit there is a miss)
{$ endif $}
