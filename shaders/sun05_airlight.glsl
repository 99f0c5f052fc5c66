// sun05_airlight.glsl: Sun et al. 2005 airlight for the GPU preview, the GLSL twin of
// native/homogeneous/sun05_inline.h (table path). Same functions, same names, same order,
// same branches; change both together (tests/gpu/test_glsl_agreement.py holds them).
// GLSL 330 compatible, no #version line (included by addon/airlight/gpu_shaders.py).
//
// Ftab: the F table of _native.special_F_table() as an R32F texture of width nT and
// height nu: texel (j, i) = data[i][j], i over s (rows of the numpy array), j over w.
// It is read with texelFetch and interpolated here (bilinear exactly as in C++), so
// the sampler's filter and wrap settings do not matter.
//   s = sqrt(u / (u + k)), k = 1 (AIRLIGHT_F_TABLE_K); tau = T (1 + u), w = tau / (1 + tau)
//   stored Q = F (1 + u) / w, so F = Q w / (1 + u).
// Out of range: none. s and w cover u, T in [0, inf] (s = 1 is u = inf, w = 1 is
// T = inf); T >= 1e30 (or inf) and Dvp >= 1e30 (or inf) are treated as infinite. The
// regularisations of the C++ are mirrored: Dsv >= 1e-6, sin(gamma) >= 1e-8 for rays
// through the light, the closed form for gamma = 0 with the light behind the surface.
// Differences with the C++ are float rounding only (expm1 / log1p use Kahan's
// compensated forms); values below ~1e-38 (sigma_t Dsv > 87) underflow to 0.

#ifndef AIRLIGHT_F_TABLE_K
#define AIRLIGHT_F_TABLE_K 1.0
#endif

const float kPi = 3.14159265358979;
const float kSinGammaMin = 1e-8;
const float kDsvMin = 1e-6;
const float kCancel = 0.125;
const float kInfinite = 1e30;

const float kGL4x[4] = float[4](0.06943184420297371, 0.33000947820757187, 0.6699905217924281,
                                0.9305681557970262);
const float kGL4w[4] = float[4](0.17392742256872692, 0.3260725774312731, 0.3260725774312731,
                                0.17392742256872692);
const float kGLx[8] = float[8](0.019855071751231856, 0.10166676129318664, 0.2372337950418355,
                               0.4082826787521751, 0.5917173212478249, 0.7627662049581645,
                               0.8983332387068134, 0.9801449282487681);
const float kGLw[8] = float[8](0.05061426814518813, 0.11119051722668724, 0.15685332293894363,
                               0.18134189168918100, 0.18134189168918100, 0.15685332293894363,
                               0.11119051722668724, 0.05061426814518813);

// expm1 / log1p without cancellation (Kahan).
float airlight_expm1(float x)
{
  float e = exp(x);
  if (e == 1.0) return x;
  float em1 = e - 1.0;
  if (em1 == -1.0) return -1.0;
  return em1 * x / log(e);
}

float airlight_log1p(float x)
{
  float v = 1.0 + x;
  if (v == 1.0) return x;
  return log(v) * x / (v - 1.0);
}

// Bilinear lookup of the stored Q(s, w).
float special_F_table_Q(sampler2D Ftab, float s, float w)
{
  ivec2 size = textureSize(Ftab, 0);  // (nT, nu)
  int nT = size.x, nu = size.y;
  float x = s * float(nu - 1), y = w * float(nT - 1);
  int i = min(int(x), nu - 2), j = min(int(y), nT - 2);
  float fx = x - float(i), fy = y - float(j);
  float q00 = texelFetch(Ftab, ivec2(j, i), 0).r, q01 = texelFetch(Ftab, ivec2(j + 1, i), 0).r;
  float q10 = texelFetch(Ftab, ivec2(j, i + 1), 0).r, q11 = texelFetch(Ftab, ivec2(j + 1, i + 1), 0).r;
  return (1.0 - fx) * ((1.0 - fy) * q00 + fy * q01) + fx * ((1.0 - fy) * q10 + fy * q11);
}

// Row coordinate s in [0, 1] of u (s = 1 is u = inf).
float special_F_table_s(float u)
{
  return sqrt(u / (u + AIRLIGHT_F_TABLE_K));
}

// F(u, T) from the table, T >= kInfinite meaning T = inf.
float special_F_table_eval(sampler2D Ftab, float u, float T)
{
  float s = special_F_table_s(u);
  float tau = T * (1.0 + u);
  float w = (T >= kInfinite) ? 1.0 : tau / (1.0 + tau);
  return special_F_table_Q(Ftab, s, w) * w / (1.0 + u);
}

// Public: F(u, T = tan v) exactly as the C++ table lookup.
float airlight_F(sampler2D Ftab, float u, float T)
{
  if (u >= kInfinite) return 0.0;
  return special_F_table_eval(Ftab, u, T);
}

// F(u, t0) and F(u, t1) with t = n / h, sharing the row coordinate.
void special_F_table_pair(sampler2D Ftab, float u, float h, float n0, float n1, bool n1_is_inf,
                          out float F0, out float F1)
{
  float s = special_F_table_s(u);
  // F = Q w / (1 + u) = Q n / (h + n (1 + u)).
  float m0 = n0 * (1.0 + u), m1 = n1 * (1.0 + u);
  float r0 = 1.0 / (h + m0), r1 = 1.0 / (h + m1);
  float w0 = m0 * r0;
  float w1 = n1_is_inf ? 1.0 : m1 * r1;
  F0 = special_F_table_Q(Ftab, s, w0) * n0 * r0;
  F1 = special_F_table_Q(Ftab, s, w1) * (n1_is_inf ? 1.0 / (1.0 + u) : n1 * r1);
}

struct Sun05Geometry {
  float Dsv, a, h, n0, n1, dn;
  float d_p;
  bool Dvp_inf;
  bool behind_limit;
};

Sun05Geometry sun05_geometry(float Dsv, float cos_gamma, float Dvp)
{
  Sun05Geometry g;
  g.Dsv = max(Dsv, kDsvMin);
  float c = clamp(cos_gamma, -1.0, 1.0);
  float omc = 1.0 - c, opc = 1.0 + c;
  float sin_g = sqrt(omc * opc);
  g.a = g.Dsv * c;
  g.behind_limit = false;
  // Ray (almost) through the light with the light in front of the surface: regularise.
  if (sin_g < kSinGammaMin && c > 0.0) {
    if (Dvp < g.Dsv && omc == 0.0) {
      g.behind_limit = true;
    } else {
      sin_g = kSinGammaMin;
      omc = 0.5 * sin_g * sin_g;
      opc = 2.0 - omc;
    }
  }
  g.h = g.Dsv * sin_g;
  g.n0 = g.Dsv * omc;
  g.Dvp_inf = Dvp >= kInfinite;
  if (g.Dvp_inf) {
    g.n1 = kInfinite; g.dn = kInfinite; g.d_p = kInfinite;
  } else {
    float dx = Dvp - g.a;
    g.d_p = sqrt(g.h * g.h + dx * dx);
    g.n1 = dx >= 0.0 ? g.d_p + dx : g.h * g.h / (g.d_p - dx);
    g.dn = 0.0;
  }
  return g;
}

// n1 - n0 without cancellation: d_p - Dsv + Dvp = Dvp (n0 + n1) / (d_p + Dsv).
void sun05_geometry_dn(inout Sun05Geometry g, float Dvp)
{
  if (!g.Dvp_inf) g.dn = Dvp * (g.n0 + g.n1) / (g.d_p + g.Dsv);
}

float sun05_direct_exp(float sigma_t, float h, float n0, float len, bool len_is_inf)
{
  float x = sigma_t * len;
  float q = len_is_inf ? 1.0 : -airlight_expm1(-x);
  float sum = 0.0;
  for (int k = 0; k < 8; ++k) {
    float n = n0 - airlight_log1p(-kGLx[k] * q) / sigma_t;
    sum += kGLw[k] / (h * h + n * n);
  }
  return sum * q / sigma_t;
}

float sun05_direct_inv(float sigma_t, float h, float n0, float na, float nb, bool nb_is_inf)
{
  float sa = 1.0 / na, sb = nb_is_inf ? 0.0 : 1.0 / nb;
  float span = sa - sb;
  float sum = 0.0;
  for (int k = 0; k < 8; ++k) {
    float rho = kGLx[k];
    float s = sb + span * rho * rho;
    sum += kGLw[k] * 2.0 * rho * exp(-sigma_t * (1.0 / s - n0)) / (1.0 + h * h * s * s);
  }
  return sum * span;
}

float sun05_direct_E(float sigma_t, Sun05Geometry g)
{
  float m = max(g.n0, g.h);
  if (!g.Dvp_inf && g.dn <= m && sigma_t * g.dn <= 1.0) {
    // Short interval, everything smooth: 4-point Gauss-Legendre in n.
    float sum = 0.0;
    for (int k = 0; k < 4; ++k) {
      float l = kGL4x[k] * g.dn, n = g.n0 + l;
      sum += kGL4w[k] * exp(-sigma_t * l) / (g.h * g.h + n * n);
    }
    return sum * g.dn;
  }
  float reach = g.Dvp_inf ? 8.0 / sigma_t : min(g.dn, 8.0 / sigma_t);
  if (g.n0 + reach <= 2.0 * m) return sun05_direct_exp(sigma_t, g.h, g.n0, g.dn, g.Dvp_inf);
  float E = 0.0, start = g.n0;
  if (g.n0 < g.h) {
    E += sun05_direct_exp(sigma_t, g.h, g.n0, g.h - g.n0, false);
    start = g.h;
  }
  return E + sun05_direct_inv(sigma_t, g.h, g.n0, start, g.n1, g.Dvp_inf);
}

float sun05_behind_limit(float sigma_t, float Dsv, float Dvp)
{
  return sigma_t * exp(-sigma_t * Dsv) * Dvp / (4.0 * kPi * Dsv * (Dsv - Dvp));
}

// Public: airlight per unit I0 and albedo (multiply by albedo * I0).
float sun05_airlight(sampler2D Ftab, float sigma_t, float Dsv, float cos_gamma, float Dvp)
{
  if (!(sigma_t > 0.0) || !(Dvp > 0.0)) return 0.0;
  Sun05Geometry g = sun05_geometry(Dsv, cos_gamma, Dvp);
  if (g.behind_limit) return sun05_behind_limit(sigma_t, g.Dsv, Dvp);
  if (g.h > 0.0) {
    float u = sigma_t * g.h;
    float F0, F1;
    special_F_table_pair(Ftab, u, g.h, g.n0, g.n1, g.Dvp_inf, F0, F1);
    float G = F1 - F0;
    if (G > kCancel * F1)
      return sigma_t / (2.0 * kPi * g.h) * exp(-sigma_t * g.a) * G;
  }
  sun05_geometry_dn(g, Dvp);
  return sigma_t / (2.0 * kPi) * exp(-sigma_t * g.Dsv) * sun05_direct_E(sigma_t, g);
}
