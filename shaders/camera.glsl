// Camera (SPEC §2): pinhole rays from the principal point C = -Dc f (it looks at the
// origin){$ if aperture $}, spread over a thin lens{$ endif $}{$ if distortion $}, through OpenCV distortion{$ endif $}.
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
    real tmin;    // the camera's (lens point's) parameter: hits need t > tmin
};
