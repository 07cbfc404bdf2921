// The linear sensor on the GPU: what develop() does in NumPy (this folder's __init__.py),
// one pixel of one frame. Electrons from the exposed radiance with their photon
// (Poisson) noise and the read noise, the black level's offset, the full well filling
// the range above it, clipped to full scale and quantised. A NaN radiance (no ray
// reached the screen) records as dark.
//
// From a mean of NORMAL_FROM_E electrons the count and the read noise are drawn as one
// normal of their summed variance, mean + sqrt(mean + read^2) z: what the Poisson law
// leaves out then is its skewness, 1/sqrt(mean) (3 % at 1000 e-, 1 % at 10 000), which
// no decoded number sees (a phase is a linear combination of the frames: its noise
// depends on their variance alone); below, the Poisson draw is exact (lib/poisson.glsl).

uniform float u_sensor_full_well_e;  // electrons at radiance 1 times the exposure
uniform float u_sensor_read_noise_e;  // electrons rms
uniform float u_sensor_black;  // recorded units (full scale 1)
uniform float u_sensor_levels;  // 2^bits - 1
uniform float u_sensor_gain;  // the exposure: recorded full well per radiance

const float NORMAL_FROM_E = 1000.0;

float sensor_record(float radiance, inout RandomStream stream)
{
    float exposed = isnan(radiance) ? 0.0 : max(radiance * u_sensor_gain, 0.0);
    float mean = exposed * u_sensor_full_well_e;
    float read2 = u_sensor_read_noise_e * u_sensor_read_noise_e;
    float electrons;
    if (mean >= NORMAL_FROM_E) {
        electrons = mean + sqrt(mean + read2) * normal_sample(stream);
    } else {
        electrons = poisson_sample(mean, stream);
        if (read2 > 0.0)
            electrons += u_sensor_read_noise_e * normal_sample(stream);
    }
    float recorded = u_sensor_black + (1.0 - u_sensor_black) * (electrons / u_sensor_full_well_e);
    return roundEven(clamp(recorded, 0.0, 1.0) * u_sensor_levels) / u_sensor_levels;
}
