#version 450
// One triangle covering the viewport. Textures hold the image's row 0 at t = 0, so t runs
// from 0 at the top of the viewport to 1 at its bottom.
out vec2 v_texcoord;
void main() {
    vec2 corner = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);
    v_texcoord = vec2(corner.x, 1.0 - corner.y);
    gl_Position = vec4(corner * 2.0 - 1.0, 0.0, 1.0);
}
