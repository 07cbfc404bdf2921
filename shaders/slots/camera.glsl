// The camera slot's contract: pixels to rays.
struct Ray {
    real3 o;      // a point of the ray near the dent, local frame, mm
    real3 d;      // unit direction
    real tmin;    // the camera's (lens point's) parameter: hits need t > tmin
};
int camera_samples();                        // rays per pixel sample (a lens's aperture samples)
Ray camera_ray(real col, real row, int k);   // ray k of sensor position (col, row), pixels, row 0 on top
