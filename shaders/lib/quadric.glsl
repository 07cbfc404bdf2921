// Quadric surfaces (sphere, cylinder): the stable roots of a ray against a quadric, and
// which of them is the first crossing of the height field from above.

// Roots of A t^2 + 2 b t + c = 0 without cancellation: the stable pair q / A and c / q,
// q = -(b + sign(b) sqrt(b^2 - A c)); false when they are not real.
bool stable_quadratic(real A, real b, real c, out real t1, out real t2) {
    real disc = b * b - A * c;
    if (disc < 0.0) return false;
    real root = sqrt(disc);
    real big = -(b + (b >= 0.0 ? root : -root));
    t1 = big / A;
    t2 = (big != 0.0) ? c / big : 0.0;
    return true;
}

// Which root of the ray/quadric intersection is the first crossing of the height field.
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
