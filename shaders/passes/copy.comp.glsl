#version 450
// The copy pass: chosen layers of a stack, over a region, into an array of the region's
// size (layer i of the copy is layer u_layer_list[i] of the stack), so that only they are
// read back.
{$ include "lib/region_pass.glsl" $}

layout(r32f, binding = 0) uniform readonly image2DArray u_stack;
layout(r32f, binding = 1) uniform writeonly image2DArray u_copy;
layout(std430, binding = 1) readonly buffer LayerList { int u_layer_list[]; };
uniform int u_layers;

void main()
{
    ivec2 local, pixel;
    if (!region_pixel(local, pixel))
        return;
    for (int i = 0; i < u_layers; ++i)
        imageStore(u_copy, ivec3(local, i), imageLoad(u_stack, ivec3(pixel, u_layer_list[i])));
}
