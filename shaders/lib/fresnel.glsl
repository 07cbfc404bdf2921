// Fresnel reflectance, unpolarised, from air onto a surface of complex index n + ik
// (a dielectric: k = 0), in real arithmetic (pbrt's FrConductor).
uniform real u_fresnel_ior;           // n
uniform real u_fresnel_extinction;    // k

float fresnel(float cos_i) {
    float c = clamp(cos_i, 0.0, 1.0);
    float c2 = c * c;
    float s2 = 1.0 - c2;
    float n2 = float(u_fresnel_ior * u_fresnel_ior);
    float k2 = float(u_fresnel_extinction * u_fresnel_extinction);
    float t0 = n2 - k2 - s2;
    float a2b2 = sqrt(t0 * t0 + 4.0 * n2 * k2);
    float t1 = a2b2 + c2;
    float a = sqrt(max(0.5 * (a2b2 + t0), 0.0));
    float t2 = 2.0 * c * a;
    float rs = (t1 - t2) / (t1 + t2);
    float t3 = c2 * a2b2 + s2 * s2;
    float t4 = t2 * s2;
    float rp = rs * (t3 - t4) / (t3 + t4);
    return 0.5 * (rs + rp);
}
