// The emitter slot's contract: where a reflected ray lands and, for the image, what it
// sees there. (u, v): screen coordinates on the emitter, mm. The reflection model says
// which of the services below it uses (template variables blur and diffuse).
bool emitter_hit(real3 p, real3 r, out real2 uv, out real dist);   // ray p + t r, t = dist
{$ if "image" in outputs $}
float emitter_radiance(real2 uv);            // the pattern's radiance at uv
{$ if blur != "none" $}
real emitter_v_rate(real3 r, real dist, real3 a);   // dv per radian of turning r towards a
{$ endif $}
{$ if blur == "gaussian" $}
float emitter_gaussian_blur(real2 uv, real variance);   // through a Gaussian of variance (mm²) along v
{$ elif blur == "ggx" $}
float emitter_ggx_blur(real2 uv, float beta);           // through a GGX slope lobe of scale beta (mm) along v
{$ endif $}
{$ if diffuse $}
float emitter_diffuse(real3 p, real3 n);     // Lambertian radiance at p with unit normal n
{$ endif $}
{$ endif $}
{$ if "frames" in outputs $}
float emitter_frame_radiance(real2 uv, int frame);   // frame number `frame` of this draw at uv
{$ endif $}
