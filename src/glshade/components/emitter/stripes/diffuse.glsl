// Lambertian reflection of the emitter (a mirror's incoherent remainder): the stripes'
// mean radiance sigma sqrt(2 pi) / P times the emitter's projected solid angle over pi,
// by Lambert's polygon formula on the emitter rectangle clipped to the tangent plane.
uniform real u_emitter_mean;       // sigma sqrt(2 pi) / P

float emitter_diffuse(real3 p, real3 n) {
    vec3 corner[4];
    vec3 centre = vec3(-u_emitter_dist * u_emitter_normal - u_emitter_offset.x * u_emitter_eu - u_emitter_offset.y * u_emitter_ev
                       - u_emitter_offset.z * u_emitter_normal - p);                  // emitter centre - p, mm
    vec3 eu = vec3(u_emitter_eu) * float(u_emitter_half.x);
    vec3 ev = vec3(u_emitter_ev) * float(u_emitter_half.y);
    corner[0] = centre - eu - ev;
    corner[1] = centre + eu - ev;
    corner[2] = centre + eu + ev;
    corner[3] = centre - eu + ev;
    vec3 nf = vec3(n);
    vec3 poly[5];                           // the rectangle clipped to n.x >= 0 (Sutherland-Hodgman)
    int count = 0;
    for (int i = 0; i < 4; ++i) {
        vec3 a = corner[i];
        vec3 b = corner[(i + 1) % 4];
        float da = dot(nf, a);
        float db = dot(nf, b);
        if (da >= 0.0) poly[count++] = a;
        if ((da >= 0.0) != (db >= 0.0)) poly[count++] = a + (b - a) * (da / (da - db));
    }
    float sum = 0.0;
    for (int i = 0; i < count; ++i) {
        vec3 a = normalize(poly[i]);
        vec3 b = normalize(poly[(i + 1) % count]);
        vec3 c = cross(a, b);
        float len = length(c);
        if (len > 0.0) sum += acos(clamp(dot(a, b), -1.0, 1.0)) * dot(nf, c) / len;
    }
    return float(u_emitter_mean) * abs(sum) / 6.2831853;
}
