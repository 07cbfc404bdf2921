// OpenCV lens distortion on normalised coordinates (x right, y down):
// xd = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2), yd likewise.
// A distorted camera's pixel shows what the ideal one shows at the undistorted point,
// found by Newton's method from the distorted one (the map does not fold inside the
// sensor: validation refuses such coefficients).
uniform real3 u_camera_distortion_radial;       // (k1, k2, k3)
uniform real2 u_camera_distortion_tangential;   // (p1, p2)

real2 undistort(real2 distorted) {
    real2 q = distorted;
    real k1 = u_camera_distortion_radial.x, k2 = u_camera_distortion_radial.y, k3 = u_camera_distortion_radial.z;
    real p1 = u_camera_distortion_tangential.x, p2 = u_camera_distortion_tangential.y;
    for (int i = 0; i < 10; ++i) {
        real x = q.x, y = q.y;
        real r2 = x * x + y * y;
        real radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        real dradial = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2);
        real2 e = real2(x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
                        y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y) - distorted;
        real a = radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x;
        real b = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y;
        real d = radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x;
        real det = a * d - b * b;
        q -= real2(d * e.x - b * e.y, a * e.y - b * e.x) / det;
    }
    return q;
}
