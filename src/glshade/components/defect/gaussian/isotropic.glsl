// Isotropic Gaussian dent (paper eq. 2 with sigma_x2 = sigma_z2, sigma_xz = 0):
// D = -dmax exp(-|q|^2 / (2 sigma^2)), q = (x - x0, z - z0) = p.xz in the local frame.
uniform real u_defect_dmax;          // mm; > 0 dent, < 0 bump
uniform real u_defect_inv_sigma2;    // 1 / sigma^2, 1/mm^2

// D at p and its gradient (dD/dx, dD/dz).
real dent(real3 p, out real2 grad) {
    real2 q = p.xz;
    real depth = -u_defect_dmax * real_exp(-0.5 * u_defect_inv_sigma2 * dot(q, q));
    grad = -depth * u_defect_inv_sigma2 * q;
    return depth;
}
