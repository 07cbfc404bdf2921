// A lobe's kernel at unit scale ({{ kernel }}): the distribution of the 2-D offset x that a
// reflection lobe maps onto the screen through its footprint matrix (a point uv + F x):
//   gaussian: x ~ N(0, I), density exp(-|x|^2 / 2) / (2 pi);
//   ggx:      density 1 / (pi (1 + |x|^2)^2), GGX's slope density at alpha = 1.
// Both are isotropic, so x's marginal along any unit direction is one 1-D law.

{$ if kernel == "ggx" $}
// x K1(x) (Abramowitz & Stegun 9.8.7 / 9.8.8): 1 at 0, falling like sqrt(x) e^-x.
float x_k1(float x) {
    if (x <= 0.0) return 1.0;
    if (x <= 2.0) {
        float t = 0.25 * x * x;
        float u = (x / 3.75) * (x / 3.75);
        float i1 = x * (0.5 + u * (0.87890594 + u * (0.51498869 + u * (0.15084934 + u * (0.02658733
                 + u * (0.00301532 + u * 0.00032411))))));
        return x * log(0.5 * x) * i1 + (1.0 + t * (0.15443144 + t * (-0.67278579 + t * (-0.18156897
                 + t * (-0.01919402 + t * (-0.00110404 + t * -0.00004686))))));
    }
    float s = 2.0 / x;
    return sqrt(x) * exp(-x) * (1.25331414 + s * (0.23498619 + s * (-0.03655620 + s * (0.01504268
           + s * (-0.00780353 + s * (0.00325614 + s * -0.00068245))))));
}
{$ endif $}

// E[cos(k x_1)]: the characteristic function of x's marginal at angular frequency k (per
// unit of x): how much of a harmonic whose phase advances k per unit of x survives.
float kernel_transfer(float k) {
{$ if kernel == "gaussian" $}
    return exp(-0.5 * k * k);
{$ else $}
    return x_k1(abs(k));
{$ endif $}
}

// Point i of a count-point lattice distributed as x: a Fibonacci lattice of the unit square
// (shifted by `shift` modulo 1), its first coordinate through the inverse CDF of |x|, its
// second an angle.
vec2 kernel_point(int i, int count, vec2 shift) {
    float u1 = fract((float(i) + 0.5) / float(count) + shift.x);
    float u2 = fract(float(i) * 0.61803399 + shift.y);
{$ if kernel == "gaussian" $}
    float radius = sqrt(-2.0 * log(1.0 - u1));
{$ else $}
    float radius = sqrt(u1 / (1.0 - u1));
{$ endif $}
    float phi = 6.2831853 * u2;
    return radius * vec2(cos(phi), sin(phi));
}
