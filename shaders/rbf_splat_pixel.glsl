// rbf_splat_pixel.glsl: the contribution of one Gaussian to one pixel's view segment, the
// GLSL twin of the bake's tiled splat kernels (native/gaussian/splat_kernels.cpp view_terms,
// light_terms, splat_gaussian: same terms, same float formulas, rbf_fast_erf_diff for
// fast_erf_diff); shared by the quad splat (rbf_splat_frag.glsl, one fragment per (pixel,
// Gaussian), summed by blending) and the tile pass (rbf_tiles_frag.glsl, one fragment per
// pixel looping over its screen tile's Gaussians). Adds to the caller's sums
//   La     += albedo_i sum_l I0_l (L_il(Dvp) - L_il(t0))   (Fogshop eq. 11, gaussian/splat.h)
//   T_seg  += T_i(0, Dvp) - T_i(0, t0)
//   T_near += T_i(0, t0)
// for the view ray origin + t dir with [t0, Dvp] the pixel's clipped segment. Gaussians
// whose cull sphere the segment [0, Dvp] misses add nothing (the bake's per-ray cull);
// the near segment [0, t0] is evaluated only where the cull sphere reaches it.
// With RBF_LIGHT_FIT 1 (the preview's default) the light side sum_l ... of L_il comes
// from the per-Gaussian quadratic fit of rbf_light_fit_frag.glsl instead (rbf_light);
// the view terms and the optical depths stay the bake's.
//
// Noise (Fogshop section 5.5, pv_noise_amp > 0; gaussian/splat.h): the optical depths T_i(0, D)
// of the view segments (D = Dvp, t0) are taken along the perturbed direction
//   r' = normalize(r + pv_noise_amp (R_i / |b_i - v|) N(b_i^r / scale + offset)),
// N = rbf_gradient_noise3 (rbf_noise.glsl), b_i^r the point of the (unperturbed) ray
// nearest b_i clamped to [0, D], R_i the bake's cull radius (eps 1e-7); the light-side
// terms keep the unperturbed ray. pv_noise = (offset, 1 / scale).
//
// Needs sun05_airlight.glsl, preview_common.glsl, rbf_gaussian.glsl and rbf_noise.glsl in
// front of it, and
//   lights      row 0 = position, row 2 = rgb: I0_l the splat multiplies by albedo_i
//   gauss       RGBA32F, RBF_TEX_WIDTH wide, 3 rows per block of W Gaussians: texel
//               (i % W, 3 (i / W) + k): k = 0 (b.xyz, a), k = 1 (c, R, R_bake / |b - v|, 0)
//               with R the preview's cull radius (preview_gaussians.CULL_EPS; 0: never
//               reaches a ray by > eps) and R_bake the bake's, k = 2 (albedo_i rgb, 0)
//   gauss_f1    RGBA32F, RBF_TEX_WIDTH wide, ceil(L / 4) rows per block: component l % 4
//               of texel (i % W, (i / W) ceil(L / 4) + l / 4) = f1 of light l and Gaussian
//               i with Gaussian i's own terms removed (one fetch per 4 lights)
// and the caller's main calls rbf_load_lights() first: the first RBF_HOIST lights'
// position and I0 are read once per pixel, not per (pixel, Gaussian).
//   gauss_light (RBF_LIGHT_FIT 1 only) RGBA32F, the quadratic fits of each Gaussian's
//               light factor F_i written by rbf_light_fit_frag.glsl (layout there): the
//               pixel evaluates the fit instead of the L exact light terms, except for
//               the Gaussians that pass flags exact (a light within RBF_FIT_NEAR R_i,
//               or dense ones).

ivec2 rbf_texel(int i, int row)
{
  return ivec2(i % RBF_TEX_WIDTH, 3 * (i / RBF_TEX_WIDTH) + row);
}

// View-ray part (view_terms): optical depth Tvp of Gaussian (rel = b - o, a, k0 = c
// sqrt(pi) / (2 a)) over [0, te] (perturbed by the noise when nscale > 0), Tvr over
// [0, b^r] and the clamped projection tr of b on the ray.
void rbf_view_terms(vec3 rel, float a, float k0, vec3 o, vec3 d, float te, float nscale,
                    out float Tvp, out float Tvr, out float tr)
{
  float ts = dot(rel, d);
  vec3 cr = cross(rel, d);
  float e = k0 * exp(-a * a * dot(cr, cr));
  float x1 = -a * ts, x2 = a * (te - ts);
  float E1 = rbf_erfc_pos(abs(x1));
  float E2 = rbf_erfc_pos(abs(x2));
  float Tvp0 = e * rbf_diff_from_erfc(x1, x2, E1, E2);
  tr = clamp(ts, 0.0, te);
  Tvr = ts <= 0.0 ? 0.0 : (ts >= te ? Tvp0 : e * (1.0 - E1));
  Tvp = Tvp0;
  if (nscale > 0.0) {
    // Perturbed direction (lookup at b^r in world space), same distance.
    vec3 n = rbf_gradient_noise3((o + tr * d) * pv_noise.w + pv_noise.xyz);
    vec3 q = d + nscale * n;
    q *= 1.0 / sqrt(max(dot(q, q), 1e-30));
    float ts2 = dot(rel, q);
    vec3 c2 = cross(rel, q);
    float e2 = k0 * exp(-a * a * dot(c2, c2));
    float y1 = -a * ts2, y2 = a * (te - ts2);
    Tvp = e2 * rbf_fast_erf_diff(y1, y2);
  }
}

// Light part (light_terms): sum_l I0_l f1_l / (4 pi) exp(-T_i(s_l, b^r) - Tvr) Tvp / |b^r - s_l|^2
// for the point p = b^r on the view ray; rbf_light_one is one light's term.
vec3 rbf_light_one(vec3 s, vec3 I0, float f1, vec3 b, float a, float k0, vec3 p, float Tvp, float Tvr)
{
  vec3 sx = p - s;
  float d2 = max(dot(sx, sx), kRbfMinD2);
  float inv = 1.0 / sqrt(d2);
  vec3 u = sx * inv;
  float Ds = d2 * inv;
  vec3 bs = b - s;
  float ts = dot(bs, u);
  vec3 c = cross(bs, u);
  float e = k0 * exp(-a * a * dot(c, c));
  float x1 = -a * ts, x2 = a * (Ds - ts);
  float Tsr = e * rbf_fast_erf_diff(x1, x2);
  return I0 * (f1 * kRbfInv4Pi * exp(-Tsr - Tvr) * Tvp / d2);
}

#ifndef PREVIEW_SHADOWS
#  define PREVIEW_SHADOWS 0
#endif
// Light l's visibility at p (PREVIEW_SHADOWS 1: its shadow-map row in lights row 2 .a,
// shadow_maps.glsl; 1 for an unshadowed light): a Gaussian's light terms are taken where
// they are evaluated (b^r, or the light fit's nodes), so a shadow edge through a Gaussian
// is blurred over it.
// A b^r clamped to the ray's surface lies on an occluder, which its own shadow map counts
// as lit: rbf_splat_pixel sets how far back along the ray (rbf_vis_dir) to look instead
// (to 98 % of the surface's distance; 0 for the light fit's nodes).
float rbf_vis_back = 0.0;
vec3 rbf_vis_dir = vec3(0.0);

float rbf_lit(int l, vec3 p)
{
#if PREVIEW_SHADOWS
  int row = int(texelFetch(lights, ivec2(l, 2), 0).a);
  return row >= 0 ? shadow_lit(row, p - rbf_vis_back * rbf_vis_dir) : 1.0;
#else
  return 1.0;
#endif
}

// The first RBF_HOIST lights (position, I0), loaded once per pixel by rbf_load_lights.
#define RBF_HOIST 4
vec3 rbf_ls[RBF_HOIST];
vec3 rbf_lI0[RBF_HOIST];

void rbf_load_lights()
{
  for (int l = 0; l < RBF_HOIST; l++) {
    rbf_ls[l] = vec3(0.0);
    rbf_lI0[l] = vec3(0.0);
    if (l < light_count) {
      rbf_ls[l] = texelFetch(lights, ivec2(l, 0), 0).xyz;
      rbf_lI0[l] = texelFetch(lights, ivec2(l, 2), 0).rgb;
    }
  }
}

// f1 of light l for Gaussian gi (gauss_f1's layout above).
float rbf_f1(int gi, int l)
{
  int rows = (light_count + 3) / 4;
  return texelFetch(gauss_f1, ivec2(gi % RBF_TEX_WIDTH, (gi / RBF_TEX_WIDTH) * rows + l / 4), 0)[l % 4];
}

// Light l's term, its inputs fetched (the rare paths: lights the fit leaves out).
vec3 rbf_light_term(int gi, int l, vec3 b, float a, float k0, vec3 p, float Tvp, float Tvr)
{
  vec3 s = texelFetch(lights, ivec2(l, 0), 0).xyz;
  vec3 I0 = texelFetch(lights, ivec2(l, 2), 0).rgb;
  return rbf_light_one(s, I0, rbf_f1(gi, l), b, a, k0, p, Tvp, Tvr) * rbf_lit(l, p);
}

vec3 rbf_light_terms(int gi, vec3 b, float a, float k0, vec3 p, float Tvp, float Tvr)
{
  int rows = (light_count + 3) / 4;
  ivec2 t = ivec2(gi % RBF_TEX_WIDTH, (gi / RBF_TEX_WIDTH) * rows);
  vec4 f1v = texelFetch(gauss_f1, t, 0);
  vec3 acc = vec3(0.0);
  // Constant bound: unrolled, the hoisted lights stay in registers.
  for (int l = 0; l < RBF_HOIST; l++) {
    if (l < light_count) {
      acc += rbf_light_one(rbf_ls[l], rbf_lI0[l], f1v[l], b, a, k0, p, Tvp, Tvr) * rbf_lit(l, p);
    }
  }
  for (int l = RBF_HOIST; l < light_count; l++) {
    acc += rbf_light_term(gi, l, b, a, k0, p, Tvp, Tvr);
  }
  return acc;
}

// Gaussian i's albedo (texel 2 of gauss).
vec3 rbf_albedo(int gi)
{
  return texelFetch(gauss, rbf_texel(gi, 2), 0).rgb;
}

#if RBF_LIGHT_FIT
// albedo_i rbf_light_terms from the fit of rbf_light_fit_frag.glsl (which includes the
// albedo): Tvp exp(-Tvr) F_i(p), F_i the
// quadratic in u = a (p - b) of the lights the fit covers (clamped at 0; one channel's fit
// for all three where those lights are grey: 3 fetches instead of 9), plus the exact
// terms of the lights it leaves out (bit l of the mask: a light near the Gaussian), or
// all exact terms where the fit pass flagged the whole Gaussian.
vec3 rbf_light(int gi, vec3 b, float a, float k0, vec3 p, float Tvp, float Tvr)
{
  ivec2 t = ivec2(gi % RBF_TEX_WIDTH, 9 * (gi / RBF_TEX_WIDTH));
  vec4 r2 = texelFetch(gauss_light, t + ivec2(0, 2), 0);
  if (r2.z == 1.0) {
    return rbf_albedo(gi) * rbf_light_terms(gi, b, a, k0, p, Tvp, Tvr);
  }
  vec3 u = a * (p - b);
  vec4 phi0 = vec4(1.0, u);
  vec4 phi1 = vec4(u.x * u.y, u.x * u.z, u.y * u.z, u.x * u.x - 0.5);
  vec2 phi2 = vec2(u.y * u.y - 0.5, u.z * u.z - 0.5);
  vec3 F = vec3(dot(texelFetch(gauss_light, t, 0), phi0) +
                dot(texelFetch(gauss_light, t + ivec2(0, 1), 0), phi1) + dot(r2.xy, phi2));
  if (r2.z == 0.0) {  // colours differ between the fitted lights: fits for g and b too
    F.g = dot(texelFetch(gauss_light, t + ivec2(0, 3), 0), phi0) +
          dot(texelFetch(gauss_light, t + ivec2(0, 4), 0), phi1) +
          dot(texelFetch(gauss_light, t + ivec2(0, 5), 0).xy, phi2);
    F.b = dot(texelFetch(gauss_light, t + ivec2(0, 6), 0), phi0) +
          dot(texelFetch(gauss_light, t + ivec2(0, 7), 0), phi1) +
          dot(texelFetch(gauss_light, t + ivec2(0, 8), 0).xy, phi2);
  }
  vec3 L = max(F, vec3(0.0)) * (exp(-Tvr) * Tvp);
  int mask = int(r2.w);
  if (mask != 0) {
    vec3 Ln = vec3(0.0);
    for (int l = 0; mask != 0; l++, mask >>= 1) {
      if ((mask & 1) != 0) {
        Ln += rbf_light_term(gi, l, b, a, k0, p, Tvp, Tvr);
      }
    }
    L += rbf_albedo(gi) * Ln;
  }
  return L;
}
#else
// albedo_i rbf_light_terms.
vec3 rbf_light(int gi, vec3 b, float a, float k0, vec3 p, float Tvp, float Tvr)
{
  return rbf_albedo(gi) * rbf_light_terms(gi, b, a, k0, p, Tvp, Tvr);
}
#endif

void rbf_splat_pixel(int gi, vec3 origin, vec3 dir, float t0, float Dvp, inout vec3 La,
                     inout float T_seg_sum, inout float T_near_sum)
{
  vec4 ba = texelFetch(gauss, rbf_texel(gi, 0), 0);
  vec4 cr = texelFetch(gauss, rbf_texel(gi, 1), 0);
  vec3 b = ba.xyz;
  float a = ba.w, c = cr.x, R = cr.y;
  // Cull like the bake: distance from b to the segment [0, Dvp] below R.
  vec3 rel = b - origin;
  float tc = dot(rel, dir);
  vec3 q = rel - clamp(tc, 0.0, Dvp) * dir;
  if (!(dot(q, q) < R * R)) {
    return;
  }
  float k0 = c * kRbfSqrtPi / (2.0 * a);
  float nscale = pv_noise_amp * cr.z;
  float Tf, Tvr, tr;
  rbf_view_terms(rel, a, k0, origin, dir, Dvp, nscale, Tf, Tvr, tr);
  rbf_vis_dir = dir;
  rbf_vis_back = max(0.0, tr - 0.98 * Dvp);
  vec3 L = rbf_light(gi, b, a, k0, origin + tr * dir, Tf, Tvr);
  rbf_vis_back = 0.0;
  float Tn = 0.0;
  // The near segment [0, t0] meets the cull sphere only if |b - o| < R + t0.
  if (t0 > 0.0 && dot(rel, rel) < (R + t0) * (R + t0)) {
    float Tvr0, tr0;
    rbf_view_terms(rel, a, k0, origin, dir, t0, nscale, Tn, Tvr0, tr0);
    L -= rbf_light(gi, b, a, k0, origin + tr0 * dir, Tn, Tvr0);
  }
  La += L;
  T_seg_sum += Tf - Tn;
  T_near_sum += Tn;
}
