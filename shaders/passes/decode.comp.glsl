#version 450
// The decode pass: each coded direction's phase-shifted frames decoded where they lie,
// as glshade.instruments.pmd.decode.decode does in NumPy (its reference). Per period k,
// the phasor sums S_k = sum_n I_n sin(d_n), C_k = sum_n I_n cos(d_n) and the total, in
// float64 and in NumPy's order; the modulation B_k = (2/N) |S_k + i C_k|, the offset A_k
// (the mean) and the wrapped phase; valid where every B_k reaches the threshold and no
// frame is NaN; the temporal unwrapping from the coarsest period down to the second
// finest in float32 (s_coarse, mm from the screen's edge). The finest period's sums come
// back as float32 pairs (the float64 sum's nearest float and the rest) and the host
// finishes in float64 (its phase and the last unwrapping step): the decoded coordinate
// keeps float64's resolution on a 500 mm screen, whatever the finest period.
//
// Layers written per direction d, from d * (6 + 3 K): S_0 and C_0 (nearest floats), S_0
// and C_0 (the rest), s_coarse (NaN for one period), valid (1 or 0), B_0..B_{K-1},
// A_0..A_{K-1}, wrapped_0..wrapped_{K-1}.
#extension GL_ARB_gpu_shader_fp64 : require
{$ include "lib/region_pass.glsl" $}

#define PERIODS {{ periods }}
#define SHIFTS {{ shifts }}
#define DIRECTIONS {{ directions }}
#define LAYERS_PER_DIRECTION (6 + 3 * PERIODS)

layout(r32f, binding = 0) uniform readonly image2DArray u_frames;
layout(r32f, binding = 1) uniform writeonly image2DArray u_maps;
uniform int u_first_layer[DIRECTIONS];  // each direction's first frame in the stack
uniform float u_extent_mm[DIRECTIONS];  // the screen's extent along each direction
uniform float u_periods_mm[PERIODS];
uniform double u_sin[SHIFTS];
uniform double u_cos[SHIFTS];
uniform double u_threshold;  // the modulation a valid pixel needs

const float TWO_PI = 6.28318530717958648;

void main()
{
    ivec2 local, pixel;
    if (!region_pixel(local, pixel))
        return;
    for (int d = 0; d < DIRECTIONS; ++d) {
        int out0 = d * LAYERS_PER_DIRECTION;
        float wrapped[PERIODS];
        bool valid = true;
        for (int k = 0; k < PERIODS; ++k) {
            precise double sine = 0.0LF;
            precise double cosine = 0.0LF;
            precise double total = 0.0LF;
            for (int n = 0; n < SHIFTS; ++n) {
                float value = imageLoad(u_frames, ivec3(pixel, u_first_layer[d] + k * SHIFTS + n)).x;
                valid = valid && !isnan(value);
                double frame = double(value);
                sine += u_sin[n] * frame;
                cosine += u_cos[n] * frame;
                total += frame;
            }
            double modulation = (2.0LF / double(SHIFTS)) * sqrt(sine * sine + cosine * cosine);
            valid = valid && modulation >= u_threshold;
            float phase = atan(float(sine), float(cosine));
            wrapped[k] = phase < 0.0 ? phase + TWO_PI : phase;
            if (k == 0) {
                float sine_hi = float(sine), cosine_hi = float(cosine);
                imageStore(u_maps, ivec3(local, out0), vec4(sine_hi));
                imageStore(u_maps, ivec3(local, out0 + 1), vec4(cosine_hi));
                imageStore(u_maps, ivec3(local, out0 + 2), vec4(float(sine - double(sine_hi))));
                imageStore(u_maps, ivec3(local, out0 + 3), vec4(float(cosine - double(cosine_hi))));
            }
            imageStore(u_maps, ivec3(local, out0 + 6 + k), vec4(float(modulation)));
            imageStore(u_maps, ivec3(local, out0 + 6 + PERIODS + k), vec4(float(total / double(SHIFTS))));
            imageStore(u_maps, ivec3(local, out0 + 6 + 2 * PERIODS + k), vec4(wrapped[k]));
        }
        float coarse = uintBitsToFloat(0x7fc00000u);
{$ if periods > 1 $}
        float period = u_periods_mm[PERIODS - 1];
        coarse = period * wrapped[PERIODS - 1] / TWO_PI;
        // past the middle of the gap beyond the screen: a coordinate just below 0
        if (coarse > 0.5 * (period + u_extent_mm[d]))
            coarse -= period;
        for (int k = PERIODS - 2; k >= 1; --k) {
            float turns = roundEven((TWO_PI * coarse / u_periods_mm[k] - wrapped[k]) / TWO_PI);
            coarse = u_periods_mm[k] * (wrapped[k] + TWO_PI * turns) / TWO_PI;
        }
{$ endif $}
        imageStore(u_maps, ivec3(local, out0 + 4), vec4(coarse));
        imageStore(u_maps, ivec3(local, out0 + 5), vec4(valid ? 1.0 : 0.0));
    }
}
