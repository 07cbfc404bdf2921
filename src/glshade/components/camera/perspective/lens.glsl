// Thin lens (pbrt's perspective camera): a disc of radius u_camera_aperture_radius on
// the principal point, perpendicular to the axis; every ray of a pixel passes through the
// point where the pixel's chief (pinhole) ray meets the plane at u_camera_focus along the axis.
uniform real u_camera_aperture_radius;   // mm: focal / (2 f_number)
uniform real u_camera_focus;             // mm along the optical axis
uniform int u_camera_aperture_samples;   // rays per pixel sample

int camera_samples() {
    return u_camera_aperture_samples;
}

// Lens point k of K on Vogel's golden-angle spiral, in mm: r = R sqrt((k + 1/2)/K), phi = k 137.5 deg.
real2 aperture_point(int k) {
    float r = sqrt((float(k) + 0.5) / float(u_camera_aperture_samples));
    float phi = float(k) * 2.39996323;
    return u_camera_aperture_radius * real2(r * cos(phi), r * sin(phi));
}

// The lens ray k of a chief ray (o at its closest approach to the dent, d, tmin at the
// principal point). With L = |F f + s| and tf = focus L / F the chief ray meets the focus
// plane at o + (tf - t0) d, t0 = Dc F / L; tf - t0 = ((focus - Dc) L^2 + Dc |s|^2) / (L F)
// keeps the difference of two 175 mm lengths out of it. The lens ray is re-originated at
// its own closest approach to the dent.
Ray lens_ray(Ray chief, real s2, real L2, real L, real3 right, real3 up, int k) {
    real lead = ((u_camera_focus - u_camera_dist) * L2 + u_camera_dist * s2) / (L * u_camera_focal);
    real3 focus_point = chief.o + lead * chief.d;
    real2 a = aperture_point(k);
    real3 w = (u_camera_focus * L / u_camera_focal) * chief.d - (a.x * right + a.y * up);  // lens point -> focus point
    real len = length(w);
    Ray ray;
    ray.d = w / len;
    real back = -dot(focus_point, ray.d);
    ray.o = focus_point + back * ray.d;
    ray.tmin = -len - back;
    return ray;
}
