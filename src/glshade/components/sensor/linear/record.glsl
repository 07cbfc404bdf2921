// The linear sensor on the GPU: what develop() does in NumPy (this folder's __init__.py),
// one pixel of one frame. Poisson electrons from the exposed radiance (exact:
// lib/poisson.glsl), normal read noise, the black level's offset, the full well filling
// the range above it, clipped to full scale and quantised. A NaN radiance (no ray reached
// the screen) records as dark.

uniform float u_sensor_full_well_e;  // electrons at radiance 1 times the exposure
uniform float u_sensor_read_noise_e;  // electrons rms
uniform float u_sensor_black;  // recorded units (full scale 1)
uniform float u_sensor_levels;  // 2^bits - 1
uniform float u_sensor_gain;  // the exposure: recorded full well per radiance

float sensor_record(float radiance, inout RandomStream stream)
{
    float exposed = isnan(radiance) ? 0.0 : max(radiance * u_sensor_gain, 0.0);
    float electrons = poisson_sample(exposed * u_sensor_full_well_e, stream);
    if (u_sensor_read_noise_e > 0.0)
        electrons += u_sensor_read_noise_e * normal_sample(stream);
    float recorded = u_sensor_black + (1.0 - u_sensor_black) * (electrons / u_sensor_full_well_e);
    return roundEven(clamp(recorded, 0.0, 1.0) * u_sensor_levels) / u_sensor_levels;
}
