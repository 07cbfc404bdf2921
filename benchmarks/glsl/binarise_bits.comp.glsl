// Every phase's binary image as bit planes: 32 neighbouring pixels of a row in one uint
// (bit i = column 32 x + i, the order of numpy.unpackbits(..., bitorder="little") on its
// little-endian bytes), one R32UI layer per phase.
layout(local_size_x = 4, local_size_y = 16) in;
layout(binding = 0, r32ui) uniform writeonly uimage2DArray u_bits;  // (words, rows, phases)

void main() {
    ivec2 id = ivec2(gl_GlobalInvocationID.xy);  // (word of 32 columns, row in the band)
    if (id.x * 32 >= u_cols || id.y >= u_rows) {
        return;
    }
    float v[32];
    for (int i = 0; i < 32; ++i) {
        int col = id.x * 32 + i;
        v[i] = col < u_cols ? cut_v(col, u_row0 + id.y) : uintBitsToFloat(0x7fc00000u);
    }
    for (int k = 0; k < u_phases; ++k) {
        uint word = 0u;
        for (int i = 0; i < 32; ++i) {
            word |= white(v[i], k) ? (1u << uint(i)) : 0u;
        }
        imageStore(u_bits, ivec3(id, k), uvec4(word));
    }
}
