// Pinhole camera (SPEC §2). The principal point is C = -Dc f (it looks at the origin).
uniform real u_cam_dist;      // Dc: origin to principal point, mm
uniform real3 u_cam_forward;  // f: unit optical axis
uniform real3 u_cam_right;    // unit image right (+x)
uniform real3 u_cam_up;       // unit image up
uniform real u_focal;         // F, mm
uniform real u_pitch;         // mm per pixel
uniform ivec2 u_size;         // (width, height) in pixels
uniform real3 u_local_origin; // O = (x0, 0, z0): the dent centre; local = world - O, mm

struct Ray {
    real3 o;      // a point of the ray near the dent, local frame, mm
    real3 d;      // unit direction
    real tmin;    // the principal point's parameter: hits need t > tmin
};

// The ray through sensor position (col, row) in pixels (row 0 at the top).
// Re-originated at its closest approach to the gazing point, written without the
// 175 mm principal point: with s the sensor offset and L^2 = F^2 + |s|^2,
//   d = (F f + s) / L,   o = C + (Dc F / L) d = Dc (F s - |s|^2 f) / L^2.
// o is formed from millimetre-sized sensor quantities, so its rounding error is a few
// ulp of |o| (near the dent: of a few mm) instead of a few ulp of 175 mm; at grazing
// views that error is stretched by 1/sin(theta) along the surface.
Ray camera_ray(real col, real row) {
    real sx = (col - real(u_size.x) * 0.5) * u_pitch;
    real sy = (real(u_size.y) * 0.5 - row) * u_pitch;
    real3 s = sx * u_cam_right + sy * u_cam_up;
    real s2 = sx * sx + sy * sy;
    real L2 = u_focal * u_focal + s2;
    real L = sqrt(L2);
    Ray ray;
    ray.d = (u_focal * u_cam_forward + s) / L;
    ray.o = u_cam_dist * (u_focal * s - s2 * u_cam_forward) / L2 - u_local_origin;
    ray.tmin = -u_cam_dist * u_focal / L;
    return ray;
}
