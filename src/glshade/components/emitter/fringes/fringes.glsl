// Phase-shifted sinusoidal fringes: offset + amplitude cos(2 pi s / P - step), s the distance
// from the screen's edge along the frame's direction, quantised to the screen's grey levels
// and displayed through its gamma. The image shows one frame (emitter_radiance); a frame
// stack shows several at once, one per layer (emitter_frame_radiance).
uniform real u_emitter_fringe_gamma;
uniform real u_emitter_fringe_levels;      // 0: continuous

// What the screen shows for a commanded value: clamped, rounded to the nearest grey level
// (halves up), then through the gamma.
float fringe_displayed(float commanded) {
    commanded = clamp(commanded, 0.0, 1.0);
    float levels = float(u_emitter_fringe_levels);
    if (levels > 0.0) commanded = floor(commanded * (levels - 1.0) + 0.5) / (levels - 1.0);
    float gamma = float(u_emitter_fringe_gamma);
    return gamma == 1.0 ? commanded : pow(commanded, gamma);
}

// The fringe at screen coordinate s (mm from the screen's edge) of period P (mm).
float fringe_level(real s, real period, float step, float offset, float amplitude) {
    const float TWO_PI = 6.2831853;
    real x = s / period;
    x -= floor(x);                                       // the fringe's fraction, in [0, 1)
    return fringe_displayed(offset + amplitude * cos(TWO_PI * float(x) - step));
}
{$ if "image" in outputs $}

uniform real2 u_emitter_fringe_axis;       // (1, 0): along u; (0, 1): along v
uniform real u_emitter_fringe_period;      // P, mm
uniform real u_emitter_fringe_step;        // 2 pi n / N, rad
uniform real u_emitter_fringe_offset;
uniform real u_emitter_fringe_amplitude;

float emitter_radiance(real2 uv) {
    real s = dot(uv + u_emitter_half, u_emitter_fringe_axis);
    return fringe_level(s, u_emitter_fringe_period, float(u_emitter_fringe_step),
                        float(u_emitter_fringe_offset), float(u_emitter_fringe_amplitude));
}
{$ endif $}
{$ if "frames" in outputs $}

// The frames of this draw: (1 along v or 0 along u, step rad, offset, amplitude) and period.
uniform vec4 u_emitter_frame[{{ frame_count }}];
uniform real u_emitter_frame_period[{{ frame_count }}];

float emitter_frame_radiance(real2 uv, int frame) {
    vec4 f = u_emitter_frame[frame];
    real s = f.x > 0.5 ? uv.y + u_emitter_half.y : uv.x + u_emitter_half.x;
    return fringe_level(s, u_emitter_frame_period[frame], f.y, f.z, f.w);
}
{$ endif $}
