// Only the crossing rows, from the bit planes that binarise_bits.comp.glsl wrote: per
// phase, the first (top) and last (bottom) pixel of every white run of each column, as
// contours.find_stripes's Runs hold them. One invocation per (word of 32 columns, phase)
// walks the band's rows twice, a word at a time: tops = here & ~above, bottoms =
// here & ~below. It counts, reserves room with one atomicAdd, and writes each crossing as
// the flat index row x cols + column of the band's cut image, its tops first, then its
// bottoms, each in row-major order. Its entry in u_table: (offset into u_found, tops,
// bottoms, 0). An invocation that finds no room writes offset 0xffffffff (the caller
// enlarges the buffer and runs again).
layout(local_size_x = 8, local_size_y = 8) in;
layout(binding = 0, r32ui) uniform readonly uimage2DArray u_bits;  // (words, rows, phases)
layout(std430, binding = 0) writeonly buffer Found { uint u_found[]; };
layout(std430, binding = 1) writeonly buffer Table { uvec4 u_table[]; };  // [phase][word]
layout(std430, binding = 2) buffer Used { uint u_used; uint u_capacity; };

uint word_at(int word, int row, int k) {
    return (row < 0 || row >= u_rows) ? 0u : imageLoad(u_bits, ivec3(word, row, k)).r;
}

// Writes one flat index per set bit of ``mask`` (columns ascending) from ``at`` on.
uint emit(uint mask, int word, int row, uint at) {
    while (mask != 0u) {
        int bit = findLSB(mask);
        u_found[at++] = uint(row * u_cols + word * 32 + bit);
        mask &= mask - 1u;
    }
    return at;
}

void main() {
    int word = int(gl_GlobalInvocationID.x);
    int k = int(gl_GlobalInvocationID.y);
    int words = (u_cols + 31) / 32;
    if (word >= words || k >= u_phases) {
        return;
    }
    uint tops = 0u;
    uint bottoms = 0u;
    for (int r = 0; r < u_rows; ++r) {
        uint here = word_at(word, r, k);
        tops += uint(bitCount(here & ~word_at(word, r - 1, k)));
        bottoms += uint(bitCount(here & ~word_at(word, r + 1, k)));
    }
    uint offset = atomicAdd(u_used, tops + bottoms);
    uint slot = uint(k * words + word);
    if (offset + tops + bottoms > u_capacity) {
        u_table[slot] = uvec4(0xffffffffu, tops, bottoms, 0u);
        return;
    }
    u_table[slot] = uvec4(offset, tops, bottoms, 0u);
    uint top_at = offset;
    uint bottom_at = offset + tops;
    for (int r = 0; r < u_rows; ++r) {
        uint here = word_at(word, r, k);
        top_at = emit(here & ~word_at(word, r - 1, k), word, r, top_at);
        bottom_at = emit(here & ~word_at(word, r + 1, k), word, r, bottom_at);
    }
}
