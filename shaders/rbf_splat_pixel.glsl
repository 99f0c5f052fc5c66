// rbf_splat_pixel.glsl: the contribution of one Gaussian to one pixel's view segment, as
// the bake's tiled splat evaluates it (native/kernels/rbf_splat.cpp splat_gaussian): shared
// by the quad splat (rbf_splat_frag.glsl, one fragment per (pixel, Gaussian), summed by
// blending) and the tile pass (rbf_tiles_frag.glsl, one fragment per pixel looping over
// its screen tile's Gaussians). Adds to the caller's sums
//   La     += albedo_i sum_l I0_l (L_il(Dvp) - L_il(t0))   (rbf_gaussian.glsl, eq. 11)
//   T_seg  += T_i(t0, Dvp)     (optical depth of the segment)
//   T_near += T_i(0, t0)       (eye to the near plane)
// for the view ray origin + t dir with [t0, Dvp] the pixel's clipped segment. Gaussians
// whose cull sphere the segment [0, Dvp] misses add nothing (the bake's per-ray cull).
//
// Noise (Fogshop section 5.5, pv_noise_amp > 0; rbf_splat.h): the optical depths of the
// view segments [0, Dvp] and [0, t0] are taken along the perturbed direction
//   r' = normalize(r + pv_noise_amp (R_i / |b_i - v|) N(b_i^r / scale + offset)),
// N = rbf_gradient_noise3 (rbf_noise.glsl), b_i^r the point of the (unperturbed) ray
// nearest b_i clamped to the segment, R_i the bake's cull radius (eps 1e-7); the
// light-side terms keep the unperturbed ray. pv_noise = (offset, 1 / scale).
//
// Needs sun05_airlight.glsl, preview_common.glsl, rbf_gaussian.glsl and rbf_noise.glsl in
// front of it, and
//   lights      row 0 = position, row 2 = rgb: I0_l the splat multiplies by albedo_i
//   gauss       RGBA32F, RBF_TEX_WIDTH wide, 3 rows per block of W Gaussians: texel
//               (i % W, 3 (i / W) + k): k = 0 (b.xyz, a), k = 1 (c, R, R_bake / |b - v|, 0)
//               with R the preview's cull radius (preview_gaussians.CULL_EPS; 0: never
//               reaches a ray by > eps) and R_bake the bake's, k = 2 (albedo_i rgb, 0)
//   gauss_f1    R32F, RBF_TEX_WIDTH wide: texel (i % W, (i / W) L + l) = f1 of light l
//               and Gaussian i with Gaussian i's own terms removed (rbf_fogshop_light)

ivec2 rbf_texel(int i, int row)
{
  return ivec2(i % RBF_TEX_WIDTH, 3 * (i / RBF_TEX_WIDTH) + row);
}

// Optical depth of Gaussian (c, a, b) on [0, D] along the noise-perturbed direction, the
// noise looked up at o + tr r (rbf_splat.cpp view_terms<true>).
float rbf_noisy_depth(vec3 b, float a, float c, vec3 o, vec3 r, float D, float tr, float nscale)
{
  vec3 n = rbf_gradient_noise3((o + tr * r) * pv_noise.w + pv_noise.xyz);
  vec3 q = r + nscale * n;
  q *= inversesqrt(max(dot(q, q), 1e-30));
  return rbf_gaussian_line_integral(c, a, b, o, q, 0.0, D);
}

void rbf_splat_pixel(int gi, vec3 origin, vec3 dir, float t0, float Dvp, inout vec3 La,
                     inout float T_seg_sum, inout float T_near_sum)
{
  vec4 ba = texelFetch(gauss, rbf_texel(gi, 0), 0);
  vec4 cr = texelFetch(gauss, rbf_texel(gi, 1), 0);
  vec3 b = ba.xyz;
  float a = ba.w, c = cr.x, R = cr.y;
  // Cull like the bake: distance from b to the segment [0, Dvp] below R.
  vec3 rel = b - origin;
  float ts = dot(rel, dir);
  vec3 q = rel - clamp(ts, 0.0, Dvp) * dir;
  if (!(dot(q, q) < R * R)) {
    return;
  }
  float Tvp, Tvr, Tvp0, Tvr0;
  vec3 xr, xr0;
  bool far_ok = rbf_fogshop_view(b, a, c, origin, dir, Dvp, Tvp, Tvr, xr);
  float T_seg, T_near;
  bool near_ok;
  if (pv_noise_amp > 0.0) {
    float nscale = pv_noise_amp * cr.z;
    Tvp = rbf_noisy_depth(b, a, c, origin, dir, Dvp, clamp(ts, 0.0, Dvp), nscale);
    T_near = t0 > 0.0 ? rbf_noisy_depth(b, a, c, origin, dir, t0, clamp(ts, 0.0, t0), nscale) : 0.0;
    T_seg = Tvp - T_near;
    near_ok = t0 > 0.0 && T_near > 1e-6 * abs(T_seg) &&
              rbf_fogshop_view(b, a, c, origin, dir, t0, Tvp0, Tvr0, xr0);
    Tvp0 = T_near;
  }
  else {
    T_seg = rbf_gaussian_line_integral(c, a, b, origin, dir, t0, Dvp);
    T_near = rbf_gaussian_line_integral(c, a, b, origin, dir, 0.0, t0);
    // L_i(t0) is proportional to T_near: skip it where it cannot matter (a Gaussian
    // away from the eye: T_near is then ~1e-10 of Tvp and the erfs cost as much again).
    near_ok = t0 > 0.0 && T_near > 1e-6 * T_seg &&
              rbf_fogshop_view(b, a, c, origin, dir, t0, Tvp0, Tvr0, xr0);
  }
  if (far_ok) {
    vec3 albedo = texelFetch(gauss, rbf_texel(gi, 2), 0).rgb;
    int row = (gi / RBF_TEX_WIDTH) * light_count;
    vec3 Lg = vec3(0.0);
    for (int l = 0; l < light_count; l++) {
      vec3 s = texelFetch(lights, ivec2(l, 0), 0).xyz;
      vec3 I0 = texelFetch(lights, ivec2(l, 2), 0).rgb;
      float f1 = texelFetch(gauss_f1, ivec2(gi % RBF_TEX_WIDTH, row + l), 0).r;
      float L = rbf_fogshop_light(b, a, c, s, f1, Tvp, Tvr, xr);
      if (near_ok) {
        L -= rbf_fogshop_light(b, a, c, s, f1, Tvp0, Tvr0, xr0);
      }
      Lg += I0 * L;
    }
    La += albedo * Lg;
  }
  T_seg_sum += T_seg;
  T_near_sum += T_near;
}
