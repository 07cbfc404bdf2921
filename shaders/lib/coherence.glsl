// Paper eq. (1), Beckmann-Spizzichino: the coherent (mirror) fraction of the reflected
// light is exp(-g), g = (2 pi sigma_h (cos i + cos r) / lambda)^2 = (4 pi sigma_h cos i / lambda)^2
// in the mirror direction; the rest is scattered (into the model's lobe).
uniform real u_reflection_coherence;     // 4 pi sigma_h / lambda

float coherent_fraction(real3 d, real3 n) {
    float k = float(u_reflection_coherence) * float(-dot(d, n));
    return exp(-k * k);
}
