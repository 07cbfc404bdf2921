// The fresnel slot's contract: the reflectance at incidence cos_i.
{$ if fresnel and shading $}
float fresnel(float cos_i);
{$ endif $}
