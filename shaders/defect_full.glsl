// Gaussian dent with a full covariance (paper eq. 2):
// D = -dmax exp(-1/2 q^T S^-1 q), q = (x - x0, z - z0) = p.xz in the local frame.
uniform real u_dmax;          // mm; > 0 dent, < 0 bump
uniform real3 u_inv_cov;      // (a, b, c): S^-1 = [[a, b], [b, c]], 1/mm^2

real dent(real3 p, out real2 grad) {
    real2 q = p.xz;
    real2 m = real2(u_inv_cov.x * q.x + u_inv_cov.y * q.y, u_inv_cov.y * q.x + u_inv_cov.z * q.y);
    real depth = -u_dmax * real_exp(-0.5 * dot(q, m));
    grad = -depth * m;
    return depth;
}
