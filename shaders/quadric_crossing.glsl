// Shared by the curved base surfaces (sphere, cylinder): which root of the ray/quadric
// intersection is the first crossing of the height field from above.
// The height field is the half of the quadric where s (y - centre_y) >= 0, s = sign(R).
// Convex: entering that half from outside is the crossing from above. Concave (a bowl
// or trough): leaving the inside downwards is. A first intersection from the back side
// (e.g. a bowl's outer wall seen from below its rim) occludes: no hit (thin shell).
// rel_near, rel_exit: heights of the two roots above the centre; t_far: where the ray
// is back above the surface (for the dent's bracket), 1e30 when never.
bool first_crossing(real R, real t_near, real t_exit, real rel_near, real rel_exit, real tmin,
                    out real t, out real t_far) {
    real s = sign(R);
    t_far = t_exit;
    if (t_near > tmin && s * rel_near >= 0.0) {
        t = t_near;
        return R > 0.0;        // convex: entering from above; concave: the back wall
    }
    if (t_exit > tmin && s * rel_exit >= 0.0) {
        t = t_exit;
        t_far = 1.0e30;
        return R < 0.0;        // concave: leaving the inside downwards
    }
    return false;
}
