// The camera's rays{$ if aperture or distortion $} (a thin lens, distortion){$ endif $}.
{$ if not aperture $}
int camera_samples() {
    return 1;                 // a pinhole: one ray per pixel sample
}

{$ endif $}
// Ray k of sensor position (col, row) in pixels (row 0 at the top).
// The chief ray is re-originated at its closest approach to the aim point T, written
// without the 175 mm principal point: with s the sensor offset and L^2 = F^2 + |s|^2,
//   d = (F f + s) / L,   o = C + (Dc F / L) d = T + Dc (F s - |s|^2 f) / L^2.
// o is formed from millimetre-sized sensor quantities, so its rounding error is a few
// ulp of |o| (near the dent: of a few mm) instead of a few ulp of 175 mm; at grazing
// views that error is stretched by 1/sin(theta) along the surface.
Ray camera_ray(real col, real row, int k) {
    real sx = (col - u_camera_centre.x) * u_camera_pitch.x;
    real sy = (u_camera_centre.y - row) * u_camera_pitch.y;
{$ if distortion $}
    real2 ideal = undistort(real2(sx, -sy) / u_camera_focal) * u_camera_focal;
    sx = ideal.x;
    sy = -ideal.y;
{$ endif $}
    real3 s = sx * u_camera_right + sy * u_camera_up;
    real s2 = sx * sx + sy * sy;
    real L2 = u_camera_focal * u_camera_focal + s2;
    real L = sqrt(L2);
    Ray ray;
    ray.d = (u_camera_focal * u_camera_forward + s) / L;
    ray.o = u_camera_dist * (u_camera_focal * s - s2 * u_camera_forward) / L2 - u_camera_local_origin;
    ray.tmin = -u_camera_dist * u_camera_focal / L;
{$ if aperture $}
    ray = lens_ray(ray, s2, L2, L, u_camera_right, u_camera_up, k);
{$ endif $}
    return ray;
}
