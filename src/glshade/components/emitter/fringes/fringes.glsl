// Phase-shifted sinusoidal fringes on a screen: pattern k commands offset + amplitude
// cos(2 pi s / P - step), s the distance from the screen's edge along the pattern's
// direction, quantised to the screen's grey levels, displayed through its response
// ({{ fringe_response }}) above its black level, plus the room light the screen reflects.
{$ if fringe_pixels $}
// The screen is a grid of pixels: a pattern is shown on pixels (s at the pixel's centre), each
// emitting from a centred square of its area, dark between them (the black matrix).
{$ endif $}
// The image shows one pattern (the scene's frame), a frame stack the frames of its draw.
uniform real u_emitter_fringe_levels;       // commanded grey levels (0: continuous)
uniform real u_emitter_fringe_step;         // one grey level, 1 / (levels - 1) (0: continuous)
{$ if fringe_response == "gamma" $}
uniform real u_emitter_fringe_gamma;        // displayed = commanded ** gamma
{$ else $}
uniform sampler2D t_emitter_response;       // the measured response: displayed at evenly spaced commanded values
{$ endif $}
uniform real u_emitter_fringe_floor;        // ambient + black level (radiance at commanded 0)
uniform real u_emitter_fringe_gain;         // 1 - black level (the white's radiance above it)
uniform vec4 u_emitter_frame[PATTERNS];     // per pattern: (1 along v / 0 along u, step rad, offset, amplitude)
uniform real u_emitter_frame_period[PATTERNS];   // per pattern: its period P, mm
{$ if fringe_pixels $}
uniform real u_emitter_pixel_pitch;         // mm
uniform real u_emitter_pixel_lit;           // half the side of a pixel's emitting square, mm
uniform real u_emitter_ambient;             // what the black matrix shows: the room light it reflects
{$ endif $}

// What the screen shows for a commanded value: clamped, rounded to the nearest grey level
// (halves up), through the response, above the black level.
float fringe_displayed(float commanded) {
    commanded = clamp(commanded, 0.0, 1.0);
    float levels = float(u_emitter_fringe_levels);
    // the level's index times the level (a product is rounded alike by every driver, a
    // quotient need not be: the white stays exactly 1)
    if (levels > 0.0) commanded = floor(commanded * (levels - 1.0) + 0.5) * float(u_emitter_fringe_step);
{$ if fringe_response == "gamma" $}
    float gamma = float(u_emitter_fringe_gamma);
    float response = gamma == 1.0 ? commanded : pow(commanded, gamma);
{$ else $}
    int samples = textureSize(t_emitter_response, 0).x;
    float at = commanded * float(samples - 1);
    int below = min(int(floor(at)), samples - 2);
    float lo = texelFetch(t_emitter_response, ivec2(below, 0), 0).r;
    float hi = texelFetch(t_emitter_response, ivec2(below + 1, 0), 0).r;
    float response = lo + (hi - lo) * (at - float(below));
{$ endif $}
    return float(u_emitter_fringe_floor) + float(u_emitter_fringe_gain) * response;
}

// Pattern k at screen coordinate s (mm from the screen's edge along its direction).
float fringe_level(real s, int k) {
    const float TWO_PI = 6.2831853;
    vec4 f = u_emitter_frame[k];
    real x = s / u_emitter_frame_period[k];
    x -= floor(x);                                       // the fringe's fraction, in [0, 1)
    return fringe_displayed(f.z + f.w * cos(TWO_PI * float(x) - f.y));
}

// The screen coordinates of uv measured from the screen's edge, mm.
real2 from_edge(real2 uv) {
    return uv + u_emitter_half;
}

float emitter_radiance(real2 uv, int pattern) {
    real2 s = from_edge(uv);
{$ if fringe_pixels $}
    real2 index = floor(s / u_emitter_pixel_pitch);
    real2 centre = (index + 0.5) * u_emitter_pixel_pitch;
    real2 off = abs(s - centre);
    if (max(off.x, off.y) > u_emitter_pixel_lit) return float(u_emitter_ambient);   // black matrix
    s = centre;
{$ endif $}
    return fringe_level(u_emitter_frame[pattern].x > 0.5 ? s.y : s.x, pattern);
}
{$ if filtered or diffuse $}

// Pattern k's displayed radiance as a function of the fringe's phase theta = 2 pi s / P -
// step, sum over h of b_h cos(h theta), h = 0 to 7 (computed in float64 from the screen's
// levels and response: its harmonics beyond the 7th are a grey level's fraction), packed
// four a vector.
uniform vec4 u_emitter_harmonics[PATTERNS * 2];

float harmonic(int pattern, int h) {
    return u_emitter_harmonics[2 * pattern + h / 4][h % 4];
}
{$ endif $}
{$ if filtered $}

// Through a lobe: each harmonic of the fringe along its direction is damped by the kernel's
// transfer at its frequency times the footprint's scale along that direction{$ if fringe_pixels $},
// and by the hold of each value over a pixel's emitting square (a box: its sinc){$ endif $}.
float filtered_series(real2 uv, real2x2 footprint, int pattern) {
    const float TWO_PI = 6.2831853;
    vec4 f = u_emitter_frame[pattern];
    bool along_v = f.x > 0.5;
    real2 s = from_edge(uv);
    real x = (along_v ? s.y : s.x) / u_emitter_frame_period[pattern];
    x -= floor(x);
    float theta = TWO_PI * float(x) - f.y;
    real2 row = along_v ? real2(footprint[0].y, footprint[1].y) : real2(footprint[0].x, footprint[1].x);
    float scale = TWO_PI * float(length(row) / u_emitter_frame_period[pattern]);   // rad per unit x
{$ if fringe_pixels $}
    float held = TWO_PI * float(u_emitter_pixel_lit / u_emitter_frame_period[pattern]);   // half its phase span
{$ endif $}
    float total = harmonic(pattern, 0);
    for (int h = 1; h < 8; ++h) {
        float b = harmonic(pattern, h);
        if (b == 0.0) continue;
        float damp = kernel_transfer(float(h) * scale);
{$ if fringe_pixels $}
        damp *= sin(float(h) * held) / (float(h) * held);
{$ endif $}
        total += b * damp * cos(float(h) * theta);
    }
    return total;
}
{$ endif $}
{$ if filtered and not fringe_pixels $}

float emitter_filtered(real2 uv, real2x2 footprint, int pattern) {
    return filtered_series(uv, footprint, pattern);
}
{$ elif filtered $}
uniform int u_emitter_footprint_samples;    // points of the lobe's kernel per filtered value

// Through a lobe over a pixelated screen. A lobe at least a pixel wide each way sees the
// pixels' average (the screen's lattice harmonics are below the kernel's transfer at 2 pi:
// 3e-9 for a Gaussian, 0.006 for GGX): the closed form, the fill factor's share of the fringe
// held on each pixel's emitting square and the black matrix's room light. A narrower one: the mean of the pattern over a lattice of the
// kernel's points mapped onto the screen.
float emitter_filtered(real2 uv, real2x2 footprint, int pattern) {
    real2 row_u = real2(footprint[0].x, footprint[1].x);
    real2 row_v = real2(footprint[0].y, footprint[1].y);
    if (min(length(row_u), length(row_v)) >= u_emitter_pixel_pitch)
        return filtered_series(uv, footprint, pattern);
    float total = 0.0;
    for (int i = 0; i < u_emitter_footprint_samples; ++i)
        total += emitter_radiance(uv + footprint * real2(kernel_point(i, u_emitter_footprint_samples, vec2(0.0))), pattern);
    return total / float(u_emitter_footprint_samples);
}
{$ endif $}
{$ if diffuse $}

// Lambertian reflection of the screen: each pattern's mean b_0 times the screen's form factor
// (lib/emitter_plane.glsl), plus its harmonics integrated against the Lambert kernel's
// marginal along the pattern's direction (the kernel integrated across it by Gauss-Legendre,
// tabulated at DIFFUSE_NODES points edge to edge and taken linear between them: each
// harmonic's integral over a stretch is then exact, whatever its period).
const int DIFFUSE_NODES = 25;
const float GAUSS_X[8] = float[8](-0.96028986, -0.79666648, -0.52553241, -0.18343464,
                                  0.18343464, 0.52553241, 0.79666648, 0.96028986);
const float GAUSS_W[8] = float[8](0.10122854, 0.22238103, 0.31370665, 0.36268378,
                                  0.36268378, 0.31370665, 0.22238103, 0.10122854);
float diffuse_form;                         // of the hit being shaded: its form factor
float diffuse_marginal[2 * DIFFUSE_NODES];  // its kernel's marginals along u, then along v (per mm)

// Lambert's kernel at the screen point (u, v) seen from p with normal n, per mm² of screen.
float lambert_kernel(vec3 to_centre, vec3 n, float u, float v) {
    vec3 x = to_centre + u * vec3(u_emitter_eu) + v * vec3(u_emitter_ev);
    float r2 = dot(x, x);
    float cos_s = max(dot(n, x), 0.0);
    float cos_e = max(-dot(vec3(u_emitter_normal), x), 0.0);
    return cos_s * cos_e / (3.14159265 * r2 * r2);
}

void diffuse_prepare(real3 p, real3 n) {
    diffuse_form = emitter_form_factor(p, n);
    vec3 to_centre = vec3(-u_emitter_dist * u_emitter_normal - u_emitter_offset.x * u_emitter_eu
                          - u_emitter_offset.y * u_emitter_ev - u_emitter_offset.z * u_emitter_normal - p);
    vec2 half_size = vec2(u_emitter_half);
    for (int j = 0; j < DIFFUSE_NODES; ++j) {
        float t = float(j) / float(DIFFUSE_NODES - 1) * 2.0 - 1.0;
        float along_u = 0.0;
        float along_v = 0.0;
        for (int g = 0; g < 8; ++g) {
            along_u += GAUSS_W[g] * lambert_kernel(to_centre, vec3(n), t * half_size.x, GAUSS_X[g] * half_size.y);
            along_v += GAUSS_W[g] * lambert_kernel(to_centre, vec3(n), GAUSS_X[g] * half_size.x, t * half_size.y);
        }
        diffuse_marginal[j] = along_u * half_size.y;
        diffuse_marginal[DIFFUSE_NODES + j] = along_v * half_size.x;
    }
}

float emitter_diffuse(real3 p, real3 n, int pattern) {
    if (pattern == 0) diffuse_prepare(p, n);  // the patterns of one hit are shaded in order
    const float TWO_PI = 6.2831853;
    vec4 f = u_emitter_frame[pattern];
    int axis = f.x > 0.5 ? 1 : 0;
    float extent = 2.0 * float(u_emitter_half[axis]);
    float width = extent / float(DIFFUSE_NODES - 1);
    float total = harmonic(pattern, 0) * diffuse_form;
    for (int h = 1; h < 8; ++h) {
        float b = harmonic(pattern, h);
        if (b == 0.0) continue;
        float c = TWO_PI * float(h) / float(u_emitter_frame_period[pattern]);   // rad per mm of s
        float phase = -float(h) * f.y;                                           // at s = 0
        float sum = 0.0;
        for (int j = 0; j + 1 < DIFFUSE_NODES; ++j) {
            float a0 = phase + c * width * float(j);
            float a1 = a0 + c * width;
            float k0 = diffuse_marginal[axis * DIFFUSE_NODES + j];
            float k1 = diffuse_marginal[axis * DIFFUSE_NODES + j + 1];
            // the integral of (k0 + (k1 - k0) t / width) cos(a0 + c t) over t in [0, width]
            float plain = (sin(a1) - sin(a0)) / c;
            float ramp = (width * sin(a1) + (cos(a1) - cos(a0)) / c) / c;
            sum += k0 * plain + (k1 - k0) * ramp / width;
        }
        total += b * sum;
    }
    return total;
}
{$ endif $}
