#version 450
// The viewer's display pass: draws one view of the scene into the window.
// mode 0: the emitter's pattern, shaded from a traced uv map at the current phase (a phase
//         change re-shades, it does not re-trace): the emitter's own emitter_radiance(uv, 0);
// mode 1: a radiance image (R32F);
// mode 2: an RGBA8 picture (contour overlay, colour-mapped displacement).
{$ for file in preamble $}
{$ include file $}
{$ endfor $}
const int PATTERNS = 1;                  // the scene's own pattern
{$ for stage in stages $}
{$ include stage.header $}
{$ for file in stage.files $}
{$ include file $}
{$ endfor $}
{$ endfor $}

uniform int u_mode;
uniform sampler2D u_uv;       // RG32F: (u, v) in mm, NaN where no emitter hit
uniform sampler2D u_gray;     // R32F radiance
uniform sampler2D u_rgba;     // RGBA8
in vec2 v_texcoord;           // (0, 0) top-left of the image
out vec4 fragment;

void main() {
    if (u_mode == 0) {
        vec2 uv = texture(u_uv, v_texcoord).xy;
        float value = isnan(uv.y) ? 0.0 : emitter_radiance(uv, 0);
        fragment = vec4(vec3(clamp(value, 0.0, 1.0)), 1.0);
    } else if (u_mode == 1) {
        fragment = vec4(vec3(clamp(texture(u_gray, v_texcoord).r, 0.0, 1.0)), 1.0);
    } else {
        fragment = vec4(texture(u_rgba, v_texcoord).rgb, 1.0);
    }
}
