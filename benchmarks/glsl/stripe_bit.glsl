#version 450
// The metric's binarisation on the GPU (benchmarks/gpu_binarise.py; not production code).
//
// The same float32 operations as glshade.metrics.visibility.binarize_v and Baseline.binary,
// in the same order, so that every pixel agrees with NumPy bit for bit:
//   w = (v - phase) / period;  w -= roundEven(w);  white = |w| < limit  and  valid
// NumPy rounds each step to float32 (phase, period and limit are float32 there too). The
// division is done in double and rounded to float: a correctly rounded float32 quotient on
// any driver (GLSL allows an inexact float division; double rounding is harmless for a
// quotient of two floats, 53 >= 2 x 24 + 2).
//
// Every kernel file is compiled after this one (the two files' texts, one after the other).

const int MAX_PHASES = 64;

layout(binding = 0) uniform sampler2D u_uv;      // the renderer's uv target: .g = v (mm), NaN = no hit
layout(binding = 1) uniform usampler2D u_valid;  // kept columns x rows: 1 where the stripes resolve

uniform int u_col0;                  // first kept column of the uv image
uniform int u_cols;                  // kept columns
uniform int u_row0;                  // first row of the band analysed
uniform int u_rows;                  // rows of the band
uniform int u_phases;                // phases of the sweep (at most MAX_PHASES)
uniform float u_phase[MAX_PHASES];   // phase shifts (mm)
uniform float u_period;              // stripe period (mm)
uniform float u_limit;               // half-width / period, as float32

// v at a kept pixel (column of the cut image, row of the image), NaN where the pixel does not
// count (no hit, or the stripes do not resolve there).
float cut_v(int col, int row) {
    float v = texelFetch(u_uv, ivec2(u_col0 + col, row), 0).g;
    bool valid = texelFetch(u_valid, ivec2(col, row), 0).r != 0u;
    return valid ? v : uintBitsToFloat(0x7fc00000u);
}

// The binary pixel at phase k from cut_v's value.
bool white(float v, int k) {
    if (isnan(v)) {
        return false;
    }
    precise float d = v - u_phase[k];
    precise float w = float(double(d) / double(u_period));
    precise float r = w - roundEven(w);
    return abs(r) < u_limit;
}
