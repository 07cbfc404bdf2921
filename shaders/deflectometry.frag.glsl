#version 450
// glshade fragment shader: one camera pixel per fragment. Composed per scene from the
// files the active components name, and nothing else: the preamble (the render slot's
// precision), then each slot's header (shaders/slots: what its component must define)
// followed by its component's files (camera, surface, defect and first hit, emitter,
// reflection, Fresnel), in that order; the shared library (shaders/lib) where they use it.
{$ for file in preamble $}
{$ include file $}
{$ endfor $}
{$ for header in preamble_headers $}
{$ include header $}
{$ endfor $}

{$ for name in outputs $}
{$ if name == "image" $}
layout(location = {{ loop.index0 }}) out float out_image;   // radiance in [0, 1]
{$ elif name == "uv" and precision == "fp64" $}
layout(location = {{ loop.index0 }}) out vec4 out_uv;       // (u, v) as float hi, lo pairs: fp64 on read-back
{$ elif name == "uv" $}
layout(location = {{ loop.index0 }}) out vec2 out_uv;       // emitter (u, v), mm; NaN: no hit
{$ elif name == "mask" $}
layout(location = {{ loop.index0 }}) out float out_mask;    // 1 where the emitter is reached
{$ elif name == "distance" $}
layout(location = {{ loop.index0 }}) out float out_distance; // camera to surface hit, mm; NaN: none
{$ elif name == "iterations" $}
layout(location = {{ loop.index0 }}) out float out_iterations; // evaluations of g by the dent solve
{$ elif name == "rays" $}
layout(location = {{ loop.index0 }}) out vec4 out_rays;     // rays traced whole, reaching the emitter, hitting the surface
{$ elif name == "frames" $}
// A stack of emitter frames, all shaded from each traced ray: one layer per frame.
layout(r32f, binding = 0) uniform writeonly image2DArray out_frames;
{$ endif $}
{$ endfor $}

{$ if shading $}
// The patterns shaded from every ray: the image's one, or the emitter frames of this draw
// (one layer each). shade() adds each pattern's pixel value, times what the surface
// reflects, to its sum.
const int PATTERNS = {{ patterns }};
float pattern_sums[PATTERNS];
{$ endif $}

{$ for stage in stages $}
{$ if stage.header $}
{$ include stage.header $}
{$ endif $}
{$ for file in stage.files $}
{$ include file $}
{$ endfor $}
{$ endfor $}

{$ if "distance" in outputs $}
float hit_distance;                          // of the last trace(): camera to hit, mm (-1: none)
{$ endif $}

// Trace ray k of sensor position (col, row) (pixel units, row 0 at the top): its first hit,
// its mirror ray's landing point uv on the emitter and, where it lands there, every pattern
// shaded into pattern_sums. False where it misses the surface or the emitter.
bool trace(real col, real row, int k, out real2 uv) {
    uv = real2(0.0);
    Ray ray = camera_ray(col, row, k);
    real3 d = ray.d;
    real3 p;
    real depth;
    real2 dent_grad;
{$ if "distance" in outputs $}
    hit_distance = -1.0;
{$ endif $}
    if (!surface_hit(ray.o, d, ray.tmin, p, depth, dent_grad)) return false;
{$ if surface_holes is defined and surface_holes $}
    if (!base_measured(p)) return false;     // a hole in the surface's data: no surface to reflect
{$ endif $}
{$ if "distance" in outputs $}
    hit_distance = float(dot(p - ray.o, d) - ray.tmin);
{$ endif $}
    real3 n = normalize(base_normal(p, depth, dent_grad));
    real3 r = d - 2.0 * dot(d, n) * n;
    real dist;
    if (!emitter_hit(p, r, uv, dist)) return false;
{$ if shading $}
{$ if fresnel $}
    shade(p, d, n, r, uv, dist, fresnel(float(-dot(d, n))));
{$ else $}
    shade(p, d, n, r, uv, dist, 1.0);
{$ endif $}
{$ endif $}
    return true;
}

{$ if supersample $}
uniform int u_render_supersample;            // rays per pixel side
{$ endif $}
{$ if supersample or aperture $}
// The slice of the pixel's sample indices this draw traces: the renderer splits a pixel's
// rays over as many draws as the driver's loop limit needs and sums them.
uniform int u_pass_first;                    // first sample index
uniform int u_pass_count;                    // samples in this draw
{$ endif $}
{$ if "rays" in outputs $}

// A loop of two iterations whose count the compiler cannot see: it runs both only when
// the driver's loop limiter (llvmpipe: 65535 iterations of all loops of a fragment
// together) has not run out, i.e. when no loop before it was cut short.
uniform int u_pass_two;                      // 2
bool loops_ran_whole() {
    int runs = 0;
    for (int i = 0; i < u_pass_two; ++i) runs += 1;
    return runs == 2;
}
{$ endif $}

void main() {
    real col = floor(real(gl_FragCoord.x));
    real row = floor(real(gl_FragCoord.y));  // framebuffer row 0 is image row 0 (top)
    real2 uv = real2(0.0);
    bool reached = false;
{$ if shading $}
    for (int j = 0; j < PATTERNS; ++j) pattern_sums[j] = 0.0;
{$ endif $}
{$ if "distance" in outputs $}
    float distance_sum = 0.0;                // over the samples that hit the surface
    int surface_hits = 0;
{$ endif $}
{$ if "iterations" in outputs $}
    g_evaluations = 0;                       // the most any sample needed
    int most_evaluations = 0;
{$ endif $}
{$ if supersample or aperture $}
    // n x n sub-pixel positions, each with the camera's rays (a lens: its aperture
    // samples): sample index i = (a n + b) K + k. This draw traces indices
    // [u_pass_first, u_pass_first + u_pass_count) and writes its share of each pattern's
    // mean (its sum over all n² K), and uv as the mean over its rays that reach the
    // emitter (the renderer weighs the draws by their counts).
    int hits = 0;
{$ if supersample $}
    int side = u_render_supersample;
{$ else $}
    const int side = 1;
{$ endif $}
    real step = 1.0 / real(side);
    int rays = camera_samples();
    int traced = 0;
    for (int i = u_pass_first; i < u_pass_first + u_pass_count; ++i) {
        int sub = i / rays;
        int k = i - sub * rays;
        int a = sub / side;
        int b = sub - a * side;
        real2 sample_uv;
{$ if "iterations" in outputs $}
        g_evaluations = 0;
{$ endif $}
        if (trace(col + (real(b) + 0.5) * step, row + (real(a) + 0.5) * step, k, sample_uv)) {
            uv += sample_uv;
            hits += 1;
        }
{$ if "distance" in outputs $}
        if (hit_distance >= 0.0) {
            distance_sum += hit_distance;
            surface_hits += 1;
        }
{$ endif $}
{$ if "iterations" in outputs $}
        most_evaluations = max(most_evaluations, g_evaluations);
{$ endif $}
        traced += 1;
    }
{$ if shading $}
    float count = float(side * side * rays);  // this draw's share of each pattern's mean: its sum over all n² K
{$ endif $}
    reached = hits > 0;
    if (reached) uv /= real(hits);
{$ if "rays" in outputs $}
    // the ray being traced when the limiter ran out was cut short: not counted
    out_rays = vec4(float(loops_ran_whole() ? traced : traced - 1), float(hits), 0.0, 0.0);
{$ if "distance" in outputs $}
    out_rays.z = float(surface_hits);
{$ endif $}
{$ endif $}
{$ else $}
    reached = trace(col + 0.5, row + 0.5, 0, uv);
{$ if shading $}
    const float count = 1.0;
{$ endif $}
{$ if "distance" in outputs $}
    if (hit_distance >= 0.0) {
        distance_sum = hit_distance;
        surface_hits = 1;
    }
{$ endif $}
{$ if "rays" in outputs $}
    out_rays = vec4(loops_ran_whole() ? 1.0 : 0.0, reached ? 1.0 : 0.0, 0.0, 0.0);
{$ if "distance" in outputs $}
    out_rays.z = float(surface_hits);
{$ endif $}
{$ endif $}
{$ if "iterations" in outputs $}
    most_evaluations = g_evaluations;
{$ endif $}
{$ endif $}
{$ if "image" in outputs $}
    out_image = pattern_sums[0] / count;
{$ elif "frames" in outputs $}
    for (int j = 0; j < PATTERNS; ++j)
        imageStore(out_frames, ivec3(gl_FragCoord.xy, j), vec4(pattern_sums[j] / count));
{$ endif $}
{$ if "uv" in outputs and precision == "fp64" $}
    vec2 uv_hi = vec2(uv);
    out_uv = reached ? vec4(uv_hi, vec2(uv - real2(uv_hi))) : vec4(uintBitsToFloat(0x7fc00000u));
{$ elif "uv" in outputs $}
    out_uv = reached ? vec2(uv) : vec2(uintBitsToFloat(0x7fc00000u));
{$ endif $}
{$ if "mask" in outputs $}
    out_mask = reached ? 1.0 : 0.0;
{$ endif $}
{$ if "distance" in outputs $}
    out_distance = surface_hits > 0 ? distance_sum / float(surface_hits) : uintBitsToFloat(0x7fc00000u);
{$ endif $}
{$ if "iterations" in outputs $}
    out_iterations = float(most_evaluations);
{$ endif $}
}
