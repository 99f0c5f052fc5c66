// rbf_gaussian.glsl: Gaussian (RBF) fog for the GPU preview, the GLSL twin of
// native/gaussian/medium.cpp (erf_diff, gaussian_line_integral) and of the per-Gaussian
// term of native/gaussian/airlight.cpp (FogshopAirlight::eval, Fogshop eq. 10-13).
// Same names, same branches; tests/gpu/test_preview_gaussians.py holds them together.
// GLSL 330 compatible, no #version line, no inputs of its own (pure functions).
//
// Density of Gaussian i: c exp(-a^2 |x - b|^2) (c amplitude 1/m, a scale 1/m, b centre).
// Line integral on o + t r, t in [t0, t1] (eq. 31):
//   c sqrt(pi) / (2 a) exp(-a^2 h^2) [erf(a (t1 - t*)) - erf(a (t0 - t*))],
//   t* = (b - o) . r, h = |(b - o) x r|.
//
// erf / erfc in float32 (GLSL has neither):
//   |x| < 0.5: Taylor series of erf to x^13 (truncation < 1e-9 relative);
//   else erfc(|x|) = t exp(-x^2 + P(t)), t = 1 / (1 + |x|/2), the Chebyshev fit of
//   Numerical Recipes (erfcc; fractional error < 1.2e-7 in exact arithmetic).
// Measured against the C++ (double) on the same inputs in
// tests/gpu/test_preview_gaussians.py (printed there).

const float kRbfSqrtPi = 1.7724538509055159;
const float kRbfTwoOverSqrtPi = 1.1283791670955126;
const float kRbfInv4Pi = 0.07957747154594767;
const float kRbfMinD2 = 1e-12;

// The fit's exponent correction P(t), t = 1 / (1 + x/2): erfc(x) = t exp(-x^2 + P(t)).
float rbf_erfc_P(float t)
{
  return -1.26551223 +
         t * (1.00002368 +
         t * (0.37409196 +
         t * (0.09678418 +
         t * (-0.18628806 +
         t * (0.27886807 +
         t * (-1.13520398 +
         t * (1.48851587 +
         t * (-0.82215223 +
         t * 0.17087277))))))));
}

// erfc(x) for x >= 0 (x may be +inf: 0).
float rbf_erfc_pos(float x)
{
  float t = 1.0 / (1.0 + 0.5 * x);
  return t * exp(-x * x + rbf_erfc_P(t));
}

// expm1 without cancellation (Kahan), as airlight_expm1 in sun05_airlight.glsl.
float rbf_expm1(float x)
{
  float e = exp(x);
  if (e == 1.0) return x;
  float em1 = e - 1.0;
  if (em1 == -1.0) return -1.0;
  return em1 * x / log(e);
}

// erfc(x1) - erfc(x2) for 0.5 <= x1 <= x2 (x2 may be inf) as
// erfc(x1) (-expm1(-(x2 - x1)(x2 + x1) + P(t2) - P(t1) + log(t2 / t1))): no cancellation
// between two exponentials and no rounding of x^2 at large x (the plain difference lost
// ~4e-5 relative in float32 on short intervals at x ~ 4).
float rbf_erfc_diff_pos(float x1, float x2)
{
  float e1 = rbf_erfc_pos(x1);
  if (isinf(x2)) return e1;
  float t1 = 1.0 / (1.0 + 0.5 * x1), t2 = 1.0 / (1.0 + 0.5 * x2);
  float w = x2 - x1;
  // log(t2 / t1) = -log1p(y), y = (w / 2) / (1 + x1 / 2)
  float y = 0.5 * w / (1.0 + 0.5 * x1);
  float v = 1.0 + y;
  float lt = (v == 1.0) ? -y : -log(v) * y / (v - 1.0);  // Kahan's log1p
  float e = -w * (x2 + x1) + (rbf_erfc_P(t2) - rbf_erfc_P(t1)) + lt;
  return e1 * -rbf_expm1(e);
}

float rbf_erf(float x)
{
  float ax = abs(x);
  if (ax < 0.5) {
    float x2 = x * x;
    // 2/sqrt(pi) sum_n (-1)^n x^(2n+1) / (n! (2n+1)), n = 0..6
    float s = 1.0 + x2 * (-1.0 / 3.0 + x2 * (1.0 / 10.0 + x2 * (-1.0 / 42.0 + x2 * (1.0 / 216.0 +
              x2 * (-1.0 / 1320.0 + x2 * (1.0 / 9360.0))))));
    return kRbfTwoOverSqrtPi * x * s;
  }
  float r = 1.0 - rbf_erfc_pos(ax);
  return x < 0.0 ? -r : r;
}

// erfc(x) for any x.
float rbf_erfc(float x)
{
  if (x >= 0.5) return rbf_erfc_pos(x);
  if (x <= -0.5) return 2.0 - rbf_erfc_pos(-x);
  return 1.0 - rbf_erf(x);
}

// erf(x2) - erf(x1) for x1 <= x2 (x2 may be +inf, x1 -inf), 0 otherwise; branches as in
// gaussian/medium.cpp erf_diff: 4-point Gauss-Legendre on a short interval, erfc differences
// when both arguments have one sign (beyond 0.5 in the ratio form of rbf_erfc_diff_pos),
// the plain difference when they straddle 0.
const float kRbfGL4x[4] = float[4](0.06943184420297371, 0.33000947820757187, 0.6699905217924281,
                                   0.9305681557970262);
const float kRbfGL4w[4] = float[4](0.17392742256872692, 0.3260725774312731, 0.3260725774312731,
                                   0.17392742256872692);

float rbf_erf_diff(float x1, float x2)
{
  if (!(x2 > x1)) return 0.0;
  float w = x2 - x1;
  float m = max(1.0, max(abs(x1), abs(x2)));
  if (w * m < 1e-2) {
    float s = 0.0;
    for (int k = 0; k < 4; k++) {
      float t = x1 + w * kRbfGL4x[k];
      s += kRbfGL4w[k] * exp(-t * t);
    }
    return kRbfTwoOverSqrtPi * w * s;
  }
  if (x1 >= 0.5) return rbf_erfc_diff_pos(x1, x2);
  if (x2 <= -0.5) return rbf_erfc_diff_pos(-x2, -x1);
  if (x1 >= 0.0) return rbf_erfc(x1) - rbf_erfc(x2);
  if (x2 <= 0.0) return rbf_erfc(-x2) - rbf_erfc(-x1);
  return rbf_erf(x2) - rbf_erf(x1);
}

// The bake's splat kernel's form (native/core/fast_erf.h fast_erf_diff): erf(x2) -
// erf(x1) for x1 <= x2 from E1 = erfc(|x1|), E2 = erfc(|x2|) only, branch-free (selects),
// as gaussian/splat_kernels.cpp evaluates every (pixel, Gaussian) pair; its error bound
// is fast_erf.h's (checked in test_preview_gaussians.py against the double erf_diff).
// rbf_splat_pixel.glsl uses it (with E1, E2 it needs anyway) so that the preview computes what the bake computes, at a
// fraction of rbf_erf_diff's cost.
float rbf_diff_from_erfc(float x1, float x2, float E1, float E2)
{
  return x1 >= 0.0 ? E1 - E2 : (x2 <= 0.0 ? E2 - E1 : 2.0 - E1 - E2);
}

float rbf_fast_erf_diff(float x1, float x2)
{
  return rbf_diff_from_erfc(x1, x2, rbf_erfc_pos(abs(x1)), rbf_erfc_pos(abs(x2)));
}

// Line integral of Gaussian (c, a, b) along o + t r, t in [t0, t1] (r unit, t1 may be inf).
float rbf_gaussian_line_integral(float c, float a, vec3 b, vec3 o, vec3 r, float t0, float t1)
{
  if (c == 0.0 || !(t1 > t0)) return 0.0;
  vec3 rel = b - o;
  float ts = dot(rel, r);
  vec3 cr = cross(rel, r);
  float h2 = dot(cr, cr);
  return c * kRbfSqrtPi / (2.0 * a) * exp(-a * a * h2) * rbf_erf_diff(a * (t0 - ts), a * (t1 - ts));
}

// View-line part of Fogshop's L_i (eq. 10-13) for the view ray o + t r, t in [0, D]
// (D may be inf): Tvp = T_i(v, p) and Tvr = T_i(v, b_i^r) of Gaussian i alone, and
// xr = b_i^r, the projection of b on the ray clamped to [0, D]. Returns false when
// Tvp == 0 (the Gaussian adds nothing to this ray).
bool rbf_fogshop_view(vec3 b, float a, float c, vec3 o, vec3 r, float D, out float Tvp,
                      out float Tvr, out vec3 xr)
{
  vec3 rel = b - o;
  float ts = dot(rel, r);
  vec3 cr = cross(rel, r);
  float k = c * kRbfSqrtPi / (2.0 * a) * exp(-a * a * dot(cr, cr));
  Tvp = 0.0;
  Tvr = 0.0;
  xr = o;
  if (k == 0.0) return false;
  float x1 = -a * ts;
  Tvp = k * rbf_erf_diff(x1, a * (D - ts));  // D = inf gives inf - ts = inf
  if (Tvp == 0.0) return false;
  float tr = clamp(ts, 0.0, D);
  Tvr = k * rbf_erf_diff(x1, a * (tr - ts));
  xr = o + tr * r;
  return true;
}

// Light part: L_i per unit I0 and albedo for the light at _s_, given the view-line part
// and f1 = exp(-(T(s, b_i) + T(v, b_i)) without Gaussian i) (computed natively per frame):
//   L_i = 1/(4 pi d^2) exp(-T_i(s, b_i^r) - T_i(v, b_i^r)) f1 T_i(v, p),  d = |b_i^r - s|.
float rbf_fogshop_light(vec3 b, float a, float c, vec3 s, float f1, float Tvp, float Tvr, vec3 xr)
{
  vec3 sx = xr - s;
  float d2 = dot(sx, sx);
  float Ds = sqrt(d2);
  float Tsr = Ds > 0.0 ? rbf_gaussian_line_integral(c, a, b, s, sx / Ds, 0.0, Ds) : 0.0;
  return kRbfInv4Pi / max(d2, kRbfMinD2) * exp(-Tsr - Tvr) * f1 * Tvp;
}

// Both parts for one light (the agreement test's entry point).
float rbf_fogshop_Li(vec3 b, float a, float c, vec3 o, vec3 r, float D, vec3 s, float f1)
{
  float Tvp, Tvr;
  vec3 xr;
  if (!rbf_fogshop_view(b, a, c, o, r, D, Tvp, Tvr, xr)) return 0.0;
  return rbf_fogshop_light(b, a, c, s, f1, Tvp, Tvr, xr);
}
