// Gaussian dent with a full covariance (paper eq. 2):
// D = -dmax exp(-1/2 q^T S^-1 q), q = (x - x0, z - z0) = p.xz in the local frame.
// The quadratic form is evaluated in the covariance's eigenbasis (computed in float64 on
// the CPU) as a sum of squares, e1^2 / l1 + e2^2 / l2: no cancellation however
// ill-conditioned S is (the entries of S^-1 reach 5e5 at condition 1e6, and
// a x^2 + 2 b x z + c z^2 then loses every digit in fp32).
uniform real u_defect_dmax;          // mm; > 0 dent, < 0 bump
uniform real2 u_defect_axis;     // (cos, sin) of the first principal axis in the (x, z) plane
uniform real2 u_defect_inv_var;      // (1 / l1, 1 / l2): inverse principal variances, 1/mm^2

real dent(real3 p, out real2 grad) {
    real2 q = p.xz;
    real c = u_defect_axis.x, s = u_defect_axis.y;
    real2 e = real2(c * q.x + s * q.y, -s * q.x + c * q.y);   // principal coordinates
    real2 m = e * u_defect_inv_var;                                   // S^-1 q in that basis
    real depth = -u_defect_dmax * real_exp(-0.5 * dot(e, m));
    grad = -depth * real2(c * m.x - s * m.y, s * m.x + c * m.y);
    return depth;
}
