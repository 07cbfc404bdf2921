#version 450
// The record pass: every layer of a stack of radiance frames as the sensor records it,
// each pixel of each frame from its own random stream (lib/philox.glsl: keyed by the
// frame's key, counted by the pixel), so a pixel records the same whatever region the
// pass covers. The sensor's GLSL (its slot's files) defines sensor_record.
{$ include "lib/region_pass.glsl" $}

layout(r32f, binding = 0) uniform readonly image2DArray u_radiance;
layout(r32f, binding = 1) uniform writeonly image2DArray u_recorded;
layout(std430, binding = 0) readonly buffer FrameKeys { uvec2 u_frame_keys[]; };
uniform int u_layers;

{$ include "lib/philox.glsl" $}

{$ include "lib/poisson.glsl" $}

{$ for file in sensor_files $}
{$ include file $}

{$ endfor $}
void main()
{
    ivec2 local, pixel;
    if (!region_pixel(local, pixel))
        return;
    for (int layer = 0; layer < u_layers; ++layer) {
        RandomStream stream = random_stream(u_frame_keys[layer], uvec2(pixel));
        float radiance = imageLoad(u_radiance, ivec3(pixel, layer)).x;
        imageStore(u_recorded, ivec3(pixel, layer), vec4(sensor_record(radiance, stream)));
    }
}
