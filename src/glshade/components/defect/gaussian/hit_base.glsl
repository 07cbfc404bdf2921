// No defect: the first hit is the base surface's (g_evaluations stays 0).
bool surface_hit(real3 o, real3 d, real tmin, out real3 p, out real depth, out real2 dent_grad) {
    real t, t_far;
    depth = 0.0;
    dent_grad = real2(0.0);
    if (!base_hit(o, d, 0.0, tmin, t, t_far)) return false;
    p = o + t * d;
    return true;
}
