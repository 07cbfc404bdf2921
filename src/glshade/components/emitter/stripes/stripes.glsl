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

float emitter_radiance(real2 uv) {
    return stripes(uv.y, u_emitter_sigma);
}
{$ if blur == "gaussian" $}

// A Gaussian stripe convolved with a Gaussian of variance s^2 along v stays Gaussian:
// width sqrt(sigma^2 + s^2), peak sigma / sqrt(sigma^2 + s^2).
float emitter_gaussian_blur(real2 uv, real variance) {
    real width = sqrt(u_emitter_sigma * u_emitter_sigma + variance);
    return float(u_emitter_sigma / width) * stripes(uv.y, width);
}
{$ elif blur == "ggx" $}

float x_k1(float x) {                         // x K1(x), Abramowitz & Stegun 9.8.7 / 9.8.8
    if (x <= 2.0) {
        float t = 0.25 * x * x;
        float u = (x / 3.75) * (x / 3.75);
        float i1 = x * (0.5 + u * (0.87890594 + u * (0.51498869 + u * (0.15084934 + u * (0.02658733
                 + u * (0.00301532 + u * 0.00032411))))));
        return x * log(0.5 * x) * i1 + (1.0 + t * (0.15443144 + t * (-0.67278579 + t * (-0.18156897
                 + t * (-0.01919402 + t * (-0.00110404 + t * -0.00004686))))));
    }
    float s = 2.0 / x;
    return sqrt(x) * exp(-x) * (1.25331414 + s * (0.23498619 + s * (-0.03655620 + s * (0.01504268
           + s * (-0.00780353 + s * (0.00325614 + s * -0.00068245))))));
}

// Through GGX's slope marginal along v, alpha^2 / (2 (alpha^2 + s^2)^(3/2)) scaled by beta:
// its characteristic function is beta w K1(beta w), which damps each Fourier harmonic of
// the Gaussian stripes.
float emitter_ggx_blur(real2 uv, float beta) {
    const float TWO_PI = 6.2831853;
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
        float damp = beta > 0.0 ? x_k1(beta * omega) : 1.0;
        total += 2.0 * envelope * damp * cos(omega * float(w));
    }
    return scale * total;
}
{$ endif $}
