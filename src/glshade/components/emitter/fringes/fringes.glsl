// One frame of phase-shifted sinusoidal fringes: offset + amplitude cos(2 pi s / P - step),
// s the distance from the screen's edge along the frame's direction, quantised to the
// screen's grey levels and displayed through its gamma.
uniform real2 u_emitter_fringe_axis;       // (1, 0): along u; (0, 1): along v
uniform real u_emitter_fringe_period;      // P, mm
uniform real u_emitter_fringe_step;        // 2 pi n / N, rad
uniform real u_emitter_fringe_offset;
uniform real u_emitter_fringe_amplitude;
uniform real u_emitter_fringe_gamma;
uniform real u_emitter_fringe_levels;      // 0: continuous

float emitter_radiance(real2 uv) {
    const float TWO_PI = 6.2831853;
    real s = dot(uv + u_emitter_half, u_emitter_fringe_axis);
    real x = s / u_emitter_fringe_period;
    x -= floor(x);                                       // the fringe's fraction, in [0, 1)
    float commanded = float(u_emitter_fringe_offset)
        + float(u_emitter_fringe_amplitude) * cos(TWO_PI * float(x) - float(u_emitter_fringe_step));
    commanded = clamp(commanded, 0.0, 1.0);
    float levels = float(u_emitter_fringe_levels);
    if (levels > 0.0) commanded = floor(commanded * (levels - 1.0) + 0.5) / (levels - 1.0);
    return pow(commanded, float(u_emitter_fringe_gamma));
}
