// Pinhole camera (SPEC §2). Coordinates are local: the world shifted by the dent centre
// (x0, 0, z0), so everything near the dent is a small number.
uniform real3 u_cam_pos;      // principal point, local frame, mm
uniform real3 u_cam_forward;  // unit optical axis
uniform real3 u_cam_right;    // unit image right (+x)
uniform real3 u_cam_up;       // unit image up
uniform real u_focal;         // mm
uniform real u_pitch;         // mm per pixel
uniform ivec2 u_size;         // (width, height) in pixels

// Unit direction of the ray through sensor position (col + fx, row + fy), fx, fy in [0, 1).
real3 camera_ray(real col, real row) {
    real sx = (col - real(u_size.x) * 0.5) * u_pitch;
    real sy = (real(u_size.y) * 0.5 - row) * u_pitch;
    return normalize(u_focal * u_cam_forward + sx * u_cam_right + sy * u_cam_up);
}
