// rbf_light_fit_frag.glsl: per Gaussian, a quadratic fit of its light factor (issue 5: the
// per-(pixel, Gaussian, light) light terms dominated the tile pass). Fogshop's L_i
// (rbf_splat_pixel.glsl rbf_light_terms) is Tvp exp(-Tvr) F_i(b^r) with
//   F_i(p) = albedo_i sum_l I0_l f1_il / (4 pi) exp(-T_i(s_l, p)) / |p - s_l|^2,
// evaluated at the foot b^r of b_i on the view ray, which lies within the cull radius R_i
// of b_i wherever the pixel sees the Gaussian. This pass projects F_i (the exact GLSL,
// rbf_light_terms with Tvp = 1, Tvr = 0) onto the 10 Hermite functions of degree <= 2 in
// u = a (p - b) under the Gaussian's own weight exp(-|u|^2) (3x3x3 Gauss-Hermite nodes,
// exact for the projection of polynomials of degree <= 3 per axis), so that a pixel pays
// one polynomial (rbf_light_fitted) instead of L exact light terms. Where the fit is not
// accurate (measured: tests/gpu/test_preview_light_fit.py) the pixels keep exact terms:
//   - a light l within RBF_FIT_NEAR R_i of b_i (1/d^2 varies too fast over the Gaussian:
//     Fogshop's "light next to a Gaussian" case stays exact) is left out of the fit and
//     marked in a mask (bit l, l < 24: exact in a float); the pixels add its exact term;
//   - the whole Gaussian is flagged exact when its own peak optical depth c sqrt(pi) / a
//     exceeds RBF_FIT_MAX_T (its self-shadowing exp(-T_i(s, p)) is erf-shaped across
//     the Gaussian, not quadratic) or a light l >= 24 is near.
//
// Output gauss_light (RGBA32F, RBF_TEX_WIDTH wide, 9 rows per block of W Gaussians):
// texel (i % W, 9 (i / W) + 3 ch + k), ch = colour channel, holds the coefficients of
//   k = 0: (1, u.x, u.y, u.z), k = 1: (u.x u.y, u.x u.z, u.y u.z, u.x^2 - 1/2),
//   k = 2: (u.y^2 - 1/2, u.z^2 - 1/2, flag, mask)   (flag, in every channel's row: 1 = all
//   lights exact per pixel, coefficients 0; 2 = the fitted lights are grey (I0 r = g = b):
//   the pixels read channel 0's rows only; 0 = rgb fits. mask: the near lights' bits,
//   in the ch = 0 row only)
// Needs what rbf_splat_pixel.glsl needs (lights, gauss, gauss_f1, light_count), compiled
// with RBF_LIGHT_FIT 0 (it uses the exact terms). Drawn over the whole texture, no blending.

void main()
{
  rbf_load_lights();
  ivec2 q = ivec2(gl_FragCoord.xy);
  int gi = q.x + RBF_TEX_WIDTH * (q.y / 9);
  int k = q.y % 9;
  int ch = k / 3, part = k % 3;
  vec4 ba = texelFetch(gauss, rbf_texel(gi, 0), 0);
  vec4 cr = texelFetch(gauss, rbf_texel(gi, 1), 0);
  vec3 b = ba.xyz;
  float a = ba.w, c = cr.x, R = cr.y;
  frag_near = vec4(0.0);
  frag_color = vec4(0.0);
  if (!(a > 0.0) || !(c > 0.0) || !(R > 0.0)) {
    return;  // padding, or a Gaussian no pixel sees (R = 0)
  }
  float k0 = c * kRbfSqrtPi / (2.0 * a);
  bool exact = 2.0 * k0 > RBF_FIT_MAX_T;
  int mask = 0;
  for (int l = 0; l < light_count; l++) {
    vec3 sb = texelFetch(lights, ivec2(l, 0), 0).xyz - b;
    if (dot(sb, sb) < (RBF_FIT_NEAR * R) * (RBF_FIT_NEAR * R)) {
      if (l < 24) mask |= 1 << l;
      else exact = true;
    }
  }
  if (exact) {
    if (part == 2) frag_color = vec4(0.0, 0.0, 1.0, 0.0);
    return;
  }
  vec3 albedo = rbf_albedo(gi);
  bool grey = true;
  for (int l = 0; l < light_count; l++) {
    vec3 I0 = albedo * texelFetch(lights, ivec2(l, 2), 0).rgb;
    if ((l >= 24 || (mask & (1 << l)) == 0) && (I0.r != I0.g || I0.r != I0.b)) grey = false;
  }
  // Gauss-Hermite, 3 nodes per axis, weights normalised to sum 1.
  const float kNode = 1.2247448713915890;  // sqrt(3/2)
  vec4 acc = vec4(0.0);
  for (int n = 0; n < 27; n++) {
    ivec3 j = ivec3(n % 3, (n / 3) % 3, n / 9) - 1;
    vec3 u = vec3(j) * kNode;
    vec3 wk = mix(vec3(2.0 / 3.0), vec3(1.0 / 6.0), vec3(abs(j)));
    float w = wk.x * wk.y * wk.z;
    vec3 p = b + u / a;
    float F = 0.0;
    for (int l = 0; l < light_count; l++) {
      if (l >= 24 || (mask & (1 << l)) == 0) {
        F += albedo[ch] * rbf_light_term(gi, l, b, a, k0, p, 1.0, 0.0)[ch];
      }
    }
    vec4 phi = part == 0 ? vec4(1.0, u) :
               (part == 1 ? vec4(u.x * u.y, u.x * u.z, u.y * u.z, u.x * u.x - 0.5) :
                            vec4(u.y * u.y - 0.5, u.z * u.z - 0.5, 0.0, 0.0));
    acc += (w * F) * phi;
  }
  // Divide by the basis functions' squared norms (1, 1/2, 1/4, 1/2 under the weight).
  vec4 inv_norm = part == 0 ? vec4(1.0, 2.0, 2.0, 2.0) :
                  (part == 1 ? vec4(4.0, 4.0, 4.0, 2.0) : vec4(2.0, 2.0, 0.0, 0.0));
  frag_color = acc * inv_norm;
  if (part == 2) {
    frag_color.z = grey ? 2.0 : 0.0;
    if (ch == 0) frag_color.w = float(mask);
  }
}
