// Every phase's binary image, one R8UI layer each (0 or 1 per pixel of the band):
// one invocation per pixel, v fetched once.
layout(local_size_x = 16, local_size_y = 4) in;
layout(binding = 0, r8ui) uniform writeonly uimage2DArray u_layers;  // (cols, rows, phases)

void main() {
    ivec2 id = ivec2(gl_GlobalInvocationID.xy);  // (column of the cut image, row in the band)
    if (id.x >= u_cols || id.y >= u_rows) {
        return;
    }
    float v = cut_v(id.x, u_row0 + id.y);
    for (int k = 0; k < u_phases; ++k) {
        imageStore(u_layers, ivec3(id, k), uvec4(white(v, k) ? 1u : 0u));
    }
}
