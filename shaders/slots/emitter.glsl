// The emitter slot's contract: where a reflected ray lands and what it sees there. (u, v):
// screen coordinates on the emitter, mm. A program shades PATTERNS patterns from every ray
// (the image: the scene's own; a frame stack: the frames of the draw), numbered 0 to
// PATTERNS - 1. The reflection model says which of the services below it uses (template
// variables filtered and diffuse).
bool emitter_hit(real3 p, real3 r, out real2 uv, out real dist);   // ray p + t r, t = dist
{$ if shading $}
float emitter_radiance(real2 uv, int pattern);       // pattern number `pattern` at uv
{$ if filtered $}
// How the landing point moves as the ray turns: column j is d(uv)/d(eps) for the ray
// r + eps a_j (mm per radian for a unit a_j orthogonal to r), dist mm from p along r.
real2x2 emitter_jacobian(real3 p, real3 r, real dist, real3 a1, real3 a2);
// The pattern seen through a lobe: its radiance averaged over the points uv + footprint x,
// x distributed as the lobe's kernel at unit scale (lib/kernels.glsl, template variable
// kernel); a closed form where the pattern has one, else a sampled average.
float emitter_filtered(real2 uv, real2x2 footprint, int pattern);
{$ endif $}
{$ if diffuse $}
float emitter_diffuse(real3 p, real3 n, int pattern);   // Lambertian radiance at p, unit normal n
{$ endif $}
{$ endif $}
