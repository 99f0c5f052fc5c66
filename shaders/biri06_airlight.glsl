// biri06_airlight.glsl: Biri et al. 2006 airlight of a point light for any phase function
// in homogeneous fog, the GLSL twin of biri06_airlight(..., GammaEval::Table) in
// native/homogeneous/biri06.cpp (same names, same branches; the derivation is in biri06.h).
// Needs sun05_airlight.glsl in front of it (kPi, kInfinite, kSinGammaMin, kDsvMin,
// airlight_expm1, airlight_log1p, kGLx / kGLw).
//
// Gtab: `_native.biri06_table(phase, g)["data"]` (the very table the bake uses) as an R32F
// texture of width nT and height nl (texel (j, i) = data[i][j]), read with texelFetch and
// interpolated here exactly as Biri06Table::eval. phase = (kind, g, K, k): kind 0
// isotropic, 1 Henyey-Greenstein (g > 0 forward, Cycles' sign), 2 Rayleigh, 3 hazy Mie,
// 4 murky Mie; K, k the table's column stretch and row scale (from the same dict).
//
// Where the table difference would cancel (G1 - G0 <= G1 / 16, or overflow), the C++ takes
// an adaptive quadrature; here 8-point Gauss-Legendre panels on a geometric ladder
// (biri06_G_diff_quad). tests/gpu/test_preview_phase_spot_sun.py measures the difference.

const float kBiriCancel = 0.0625;
const float kBiriInv4Pi = 0.07957747154594767;

float biri06_phase(vec4 phase, float mu)
{
  mu = clamp(mu, -1.0, 1.0);
  int kind = int(phase.x + 0.5);
  if (kind == 1) {
    float g = phase.y;
    float denom = 1.0 + g * g - 2.0 * g * mu;
    return kBiriInv4Pi * (1.0 - g * g) / (denom * sqrt(denom));
  }
  if (kind == 2) return 3.0 * kBiriInv4Pi / 4.0 * (1.0 + mu * mu);
  if (kind == 3) {
    float s = 0.5 * (1.0 + mu), s2 = s * s, s4 = s2 * s2;
    return kBiriInv4Pi / 2.0 * (1.0 + 9.0 * s4 * s4);
  }
  if (kind == 4) {
    float s = 0.5 * (1.0 + mu), s2 = s * s, s4 = s2 * s2, s8 = s4 * s4, s16 = s8 * s8;
    return 33.0 * kBiriInv4Pi / 83.0 * (1.0 + 50.0 * s16 * s16);
  }
  return kBiriInv4Pi;
}

// G(lambda, T) from the table (Biri06Table::eval).
float biri06_table_G(sampler2D Gtab, vec4 phase, float lambda, float T)
{
  if (isinf(lambda)) return 0.0;
  float K = phase.z, k = phase.w;
  ivec2 size = textureSize(Gtab, 0);  // (nT, nl)
  float s = sqrt(lambda / (lambda + k));
  float tau = T * (K + lambda);
  float w = (isinf(T) || T >= kInfinite) ? 1.0 : tau / (1.0 + tau);
  float x = s * float(size.y - 1), y = w * float(size.x - 1);
  int i = min(int(x), size.y - 2), j = min(int(y), size.x - 2);
  float fx = x - float(i), fy = y - float(j);
  float q00 = texelFetch(Gtab, ivec2(j, i), 0).r, q01 = texelFetch(Gtab, ivec2(j + 1, i), 0).r;
  float q10 = texelFetch(Gtab, ivec2(j, i + 1), 0).r, q11 = texelFetch(Gtab, ivec2(j + 1, i + 1), 0).r;
  float Q = (1.0 - fx) * ((1.0 - fy) * q00 + fy * q01) + fx * ((1.0 - fy) * q10 + fy * q11);
  return Q * w / (K + lambda);
}

// Scaled G difference (biri06_G_diff_exact): int_{theta0}^{theta1} p(cos theta)
// exp(-lambda [tan(theta/2) - tan(theta0/2)]) dtheta, the bracket written as
// sin((theta - theta0)/2) / (cos(theta/2) cos(theta0/2)) (no cancellation). 8-point
// Gauss-Legendre panels on a geometric ladder from theta0 (first width the smaller of the
// extinction layer 2 cos^2(theta0/2) / lambda and the phase lobe, then x4), as the C++
// places its breakpoints; at most 12 panels, the last one ends at theta1.
float biri06_G_diff_quad(vec4 phase, float lambda, float theta0, float theta1)
{
  if (!(theta1 > theta0)) return 0.0;
  float c0 = cos(0.5 * theta0);
  int kind = int(phase.x + 0.5);
  float lobe = kind == 1 ? max(1.0 - abs(phase.y), 1e-3) : (kind == 4 ? 0.25 : 1.0);
  float w = lobe;
  if (lambda > 0.0) w = min(w, 2.0 * c0 * c0 / lambda);
  w = max(w, (theta1 - theta0) * 1e-6);
  float sum = 0.0;
  float lo = theta0;
  for (int panel = 0; panel < 12; panel++) {
    float hi = (panel == 11) ? theta1 : min(lo + w, theta1);
    float len = hi - lo;
    float part = 0.0;
    for (int k = 0; k < 8; k++) {
      float theta = lo + len * kGLx[k];
      float p = biri06_phase(phase, cos(theta));
      float ch = cos(0.5 * theta);
      float f = (lambda == 0.0) ? p : (ch <= 0.0 ? 0.0 : p * exp(-lambda * sin(0.5 * (theta - theta0)) / (ch * c0)));
      part += kGLw[k] * f;
    }
    sum += part * len;
    lo = hi;
    if (lo >= theta1) break;
    w *= 4.0;
  }
  return sum;
}

// Airlight per unit I0 and albedo (biri06_airlight in biri06.cpp).
float biri06_airlight(sampler2D Gtab, vec4 phase, float sigma_t, float Dsv, float cos_gamma, float Dvp)
{
  if (sigma_t == 0.0 || Dvp == 0.0) return 0.0;
  Dsv = max(Dsv, kDsvMin);
  float c = clamp(cos_gamma, -1.0, 1.0);
  float sin_gamma = max(sqrt((1.0 - c) * (1.0 + c)), kSinGammaMin);
  float h = Dsv * sin_gamma, a = Dsv * c, lambda = sigma_t * h;
  bool far = isinf(Dvp) || Dvp >= kInfinite;
  float am = a - Dvp;
  float d1 = far ? kInfinite : length(vec2(am, h));
  float T0 = c >= 0.0 ? sin_gamma / (1.0 + c) : (1.0 - c) / sin_gamma;
  float T1 = far ? kInfinite : (am >= 0.0 ? h / (d1 + am) : (d1 - am) / h);
  float G1 = biri06_table_G(Gtab, phase, lambda, T1), G0 = biri06_table_G(Gtab, phase, lambda, T0);
  float D = G1 - G0;
  float La = sigma_t / h * exp(-sigma_t * a) * D;
  if (D > kBiriCancel * G1 && !isinf(La) && !isnan(La)) return La;
  float theta0 = atan(sin_gamma, c);
  float theta1 = far ? kPi : atan(h, am);
  return sigma_t / h * exp(-sigma_t * Dsv) * biri06_G_diff_quad(phase, lambda, theta0, theta1);
}
