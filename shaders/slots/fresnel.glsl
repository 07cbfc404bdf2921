// The fresnel slot's contract: the reflectance at incidence cos_i.
{$ if fresnel and "image" in outputs $}
float fresnel(float cos_i);
{$ endif $}
