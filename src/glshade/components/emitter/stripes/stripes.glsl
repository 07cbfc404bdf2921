// The stripes' radiance: Gaussian stripes of width u_emitter_sigma, constant along u, spaced
// u_emitter_period along v, shifted by u_emitter_phase.
uniform real u_emitter_period;    // mm
uniform real u_emitter_sigma;     // mm
uniform real u_emitter_phase;     // mm

// sum_k exp(-(v - phase - k period)^2 / (2 width^2)): narrow stripes summed directly
// (|k| <= 5 around the nearest: the next term is below exp(-40)), wide ones through
// the Poisson-summed Fourier series (terms m <= 3: the next is below exp(-70)).
float stripes(real v, real width) {
    real w = v - u_emitter_phase;
    w -= u_emitter_period * floor(w / u_emitter_period + 0.5);   // nearest stripe at w = 0
    float wf = float(w);
    float p = float(u_emitter_period);
    float s = float(width);
    float total = 0.0;
    if (s <= 0.5 * p) {
        for (int k = -5; k <= 5; ++k) {
            float x = (wf - float(k) * p) / s;
            total += exp(-0.5 * x * x);
        }
    } else {
        const float TWO_PI = 6.2831853;
        float ratio = TWO_PI * s / p;
        total = 1.0;
        for (int m = 1; m <= 3; ++m) {
            total += 2.0 * exp(-0.5 * ratio * ratio * float(m * m)) * cos(TWO_PI * float(m) * wf / p);
        }
        total *= sqrt(TWO_PI) * s / p;
    }
    return total;
}

// The stripes are one pattern: every pattern number shows them.
float emitter_radiance(real2 uv, int pattern) {
    return stripes(uv.y, u_emitter_sigma);
}
{$ if filtered $}

// The stripes vary along v only: through the footprint, v moves by row . x.
real2 v_row(real2x2 footprint) {
    return real2(footprint[0].y, footprint[1].y);
}
{$ if kernel == "gaussian" $}

// A Gaussian stripe convolved with a Gaussian of variance s^2 = |row|^2 along v stays
// Gaussian: width sqrt(sigma^2 + s^2), peak sigma / sqrt(sigma^2 + s^2).
float emitter_filtered(real2 uv, real2x2 footprint, int pattern) {
    real2 row = v_row(footprint);
    real width = sqrt(u_emitter_sigma * u_emitter_sigma + dot(row, row));
    return float(u_emitter_sigma / width) * stripes(uv.y, width);
}
{$ else $}

// Through the kernel's marginal along v, of scale beta = |row| (mm): each Fourier harmonic
// of the Gaussian stripes is damped by the kernel's transfer (lib/kernels.glsl).
float emitter_filtered(real2 uv, real2x2 footprint, int pattern) {
    const float TWO_PI = 6.2831853;
    float beta = float(length(v_row(footprint)));
    real w = uv.y - u_emitter_phase;
    w -= u_emitter_period * floor(w / u_emitter_period + 0.5);
    float p = float(u_emitter_period);
    float sigma = float(u_emitter_sigma);
    float scale = sqrt(TWO_PI) * sigma / p;
    float total = 1.0;
    for (int m = 1; m <= 64; ++m) {
        float omega = TWO_PI * float(m) / p;
        float envelope = exp(-0.5 * omega * omega * sigma * sigma);
        if (envelope < 1.0e-9) break;
        total += 2.0 * envelope * kernel_transfer(beta * omega) * cos(omega * float(w));
    }
    return scale * total;
}
{$ endif $}
{$ endif $}
