// What every pass over a region of a frame stack shares (shaders/passes/): 8 x 8 pixels a
// workgroup, the region's first pixel and size, and which pixel an invocation is.
layout(local_size_x = 8, local_size_y = 8) in;

uniform ivec2 u_origin;  // the region's first pixel: (column, row)
uniform ivec2 u_size;  // the region's (columns, rows)

// The invocation's pixel in the region (``local``) and in the image (``pixel``); false
// for an invocation past the region's edge (the last workgroups' spare ones).
bool region_pixel(out ivec2 local, out ivec2 pixel)
{
    local = ivec2(gl_GlobalInvocationID.xy);
    pixel = u_origin + local;
    return all(lessThan(local, u_size));
}
