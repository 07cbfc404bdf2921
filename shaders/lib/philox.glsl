// Philox4x32-10 (Salmon, Moraes, Dror and Shaw, "Parallel random numbers: as easy as
// 1, 2, 3", SC'11; the Random123 library's constants): a counter-based generator. Four
// 32-bit words come from a 128-bit counter and a 64-bit key by ten rounds of multiplies
// and xors, so a draw depends on its key and counter alone: not on the tiling, the order
// or the number of invocations. glshade keys a stream by the sensor's seed, the scene, the
// frame and the recording, and counts it by the pixel and the draw
// (glshade.gpu.sequence.frame_key, random_stream below).

uvec4 philox4x32_10(uvec4 counter, uvec2 key)
{
    for (int round_ = 0; round_ < 10; ++round_) {
        uint hi0, lo0, hi1, lo1;
        umulExtended(0xD2511F53u, counter.x, hi0, lo0);
        umulExtended(0xCD9E8D57u, counter.z, hi1, lo1);
        counter = uvec4(hi1 ^ counter.y ^ key.x, lo1, hi0 ^ counter.w ^ key.y, lo0);
        key += uvec2(0x9E3779B9u, 0xBB67AE85u);
    }
    return counter;
}

// One pixel's stream of a frame: counter (column, row, 0, block), four words a block.
struct RandomStream {
    uvec4 counter;
    uvec2 key;
    uvec4 block;
    int used;
};

RandomStream random_stream(uvec2 key, uvec2 pixel)
{
    return RandomStream(uvec4(pixel, 0u, 0u), key, uvec4(0u), 4);
}

// A uniform number in (0, 1): the word's top 24 bits and a half, times 2^-24 (exact in
// float32, never 0 nor 1).
float next_uniform(inout RandomStream stream)
{
    if (stream.used == 4) {
        stream.block = philox4x32_10(stream.counter, stream.key);
        stream.counter.w += 1u;
        stream.used = 0;
    }
    uint word = stream.block[stream.used];
    stream.used += 1;
    return (float(word >> 8) + 0.5) * (1.0 / 16777216.0);
}
