// Lambertian reflection of the emitter (a mirror's incoherent remainder): the stripes' mean
// radiance sigma sqrt(2 pi) / P times the emitter's form factor (lib/emitter_plane.glsl):
// the diffuse kernel spans hundreds of mm of the emitter, over which the stripes average out.
uniform real u_emitter_mean;       // sigma sqrt(2 pi) / P

float emitter_diffuse(real3 p, real3 n, int pattern) {
    return float(u_emitter_mean) * emitter_form_factor(p, n);
}
