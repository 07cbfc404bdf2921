// Poisson and normal draws from a RandomStream (lib/philox.glsl), in float32.
//
// Poisson(mean): below 10 by inversion (the cumulative sum of the probabilities, at most
// 64 terms); from 10 by Hormann's transformed rejection with squeeze (PTRS, "The
// transformed rejection method for generating Poisson random variables", 1993), NumPy's
// own algorithm for these means. Its acceptance test compares log densities of size
// ~mean, which float32 cannot subtract at a mean of 1e6: the target
// k log(mean) - mean - log k! is written about m = k + 1 with Stirling's series,
// k (log1p(x) - x) - x - log(m) / 2 - log(2 pi) / 2 - tail(m), x = (mean - m) / m, every
// term of order one. Counts above 2^24 are float32 (rounded to 1 in 2^24 of the count, far
// below its noise, sqrt of the count).

// log(1 + x) - x, without the cancellation of the two near 0.
float log1p_minus_x(float x)
{
    if (abs(x) > 0.25)
        return log(1.0 + x) - x;
    float sum = 0.0;
    for (int n = 13; n >= 2; --n)  // -x^2/2 + x^3/3 - ... (x^14 / 14 < 1e-9 at 0.25)
        sum = x * (((n % 2 == 0) ? -1.0 : 1.0) / float(n) + sum);
    return x * sum;
}

// k log(mean) - mean - log k!, the log of the Poisson probability of k.
float poisson_log_probability(float k, float mean, float log_mean)
{
    if (k < 10.0) {
        float log_factorial = 0.0;
        for (float j = 2.0; j <= k; j += 1.0)
            log_factorial += log(j);
        return k * log_mean - mean - log_factorial;
    }
    float m = k + 1.0;
    float x = (mean - m) / m;
    float inverse = 1.0 / m;
    float tail = inverse * (1.0 / 12.0 - inverse * inverse * (1.0 / 360.0 - inverse * inverse / 1260.0));
    return k * log1p_minus_x(x) - x - 0.5 * log(m) - 0.91893853320467274 - tail;
}

float poisson_inversion(float mean, inout RandomStream stream)
{
    float u = next_uniform(stream);
    float p = exp(-mean);
    float cumulative = p;
    float k = 0.0;
    for (int n = 0; n < 64 && u > cumulative; ++n) {
        k += 1.0;
        p *= mean / k;
        cumulative += p;
    }
    return k;
}

float poisson_ptrs(float mean, inout RandomStream stream)
{
    float root = sqrt(mean);
    float log_mean = log(mean);
    float b = 0.931 + 2.53 * root;
    float a = -0.059 + 0.02483 * b;
    float log_inverse_alpha = log(1.1239 + 1.1328 / (b - 3.4));
    float vr = 0.9277 - 3.6224 / (b - 2.0);
    for (int attempt = 0; attempt < 64; ++attempt) {
        float u = next_uniform(stream) - 0.5;
        float v = next_uniform(stream);
        float us = 0.5 - abs(u);
        float k = floor((2.0 * a / us + b) * u + mean + 0.43);
        if (us >= 0.07 && v <= vr)
            return k;
        if (k < 0.0 || (us < 0.013 && v > us))
            continue;
        if (log(v) + log_inverse_alpha - log(a / (us * us) + b)
            <= poisson_log_probability(k, mean, log_mean))
            return k;
    }
    return floor(mean + 0.5);  // not reached: each attempt is accepted with p > 0.8
}

float poisson_sample(float mean, inout RandomStream stream)
{
    if (!(mean > 0.0))
        return 0.0;
    return mean < 10.0 ? poisson_inversion(mean, stream) : poisson_ptrs(mean, stream);
}

// A standard normal draw (Box-Muller, the cosine branch).
float normal_sample(inout RandomStream stream)
{
    float radius = sqrt(-2.0 * log(next_uniform(stream)));
    return radius * cos(6.28318530717958648 * next_uniform(stream));
}
