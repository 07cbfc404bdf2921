// Stripe radiance of the emitter (SPEC §3): Gaussian stripes of width u_stripe_sigma,
// constant along u, spaced u_period along v, shifted by u_phase.
uniform real u_period;        // mm
uniform real u_stripe_sigma;  // mm
uniform real u_phase;         // mm

// sum_k exp(-(v - phase - k period)^2 / (2 width^2)): narrow stripes summed directly
// (|k| <= 5 around the nearest: the next term is below exp(-40)), wide ones through
// the Poisson-summed Fourier series (terms m <= 3: the next is below exp(-70)).
float stripes(real v, real width) {
    real w = v - u_phase;
    w -= u_period * floor(w / u_period + 0.5);         // nearest stripe at w = 0
    float wf = float(w);
    float p = float(u_period);
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
