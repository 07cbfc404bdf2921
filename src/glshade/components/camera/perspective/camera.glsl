// Perspective camera: pinhole rays from the principal point C = T - Dc f (it aims at T){$ if aperture $}, spread over a thin lens{$ endif $}{$ if distortion $}, through OpenCV distortion{$ endif $}.
uniform real u_camera_dist;           // Dc: aim point T to principal point, mm
uniform real3 u_camera_forward;       // f: unit optical axis
uniform real3 u_camera_right;         // unit image right (+x)
uniform real3 u_camera_up;            // unit image up
uniform real u_camera_focal;          // F, mm
uniform real2 u_camera_pitch;         // mm per pixel along x and y (F / fx, F / fy)
uniform real2 u_camera_centre;        // where the optical axis meets the sensor, pixels
uniform real3 u_camera_local_origin;  // O - T: the dent centre O from the aim point T; local = world - O, mm
