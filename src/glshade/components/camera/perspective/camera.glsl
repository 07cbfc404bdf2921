// Perspective camera: pinhole rays from the principal point C = -Dc f (it looks at the
// origin){$ if aperture $}, spread over a thin lens{$ endif $}{$ if distortion $}, through OpenCV distortion{$ endif $}.
uniform real u_camera_dist;           // Dc: origin to principal point, mm
uniform real3 u_camera_forward;       // f: unit optical axis
uniform real3 u_camera_right;         // unit image right (+x)
uniform real3 u_camera_up;            // unit image up
uniform real u_camera_focal;          // F, mm
uniform real u_camera_pitch;          // mm per pixel
uniform ivec2 u_camera_size;          // (width, height) in pixels
uniform real3 u_camera_local_origin;  // O = (x0, 0, z0): the dent centre; local = world - O, mm
