// fog_preview_frag.glsl: viewport preview of homogeneous single-scattering fog, at full
// or reduced resolution. Per output texel: the full-resolution pixel it stands for
// (texel * scale + scale / 2, so a reduced image holds exact samples of chosen pixels,
// which preview_upsample_frag.glsl knows), its view ray and surface distance, and the
// premultiplied fog of preview_common.glsl: rgb = airlight, alpha = 1 - Tr, so
// ALPHA_PREMULT blending gives L = La + Tr L_scene. With PREVIEW_LOWRES defined to 1
// (the reduced target), alpha holds the pixel's surface distance Dvp instead, which
// preview_upsample_frag.glsl compares and turns into the exact Tr per full-res pixel.
//
//   viewport    xy = lower-left corner of the target in the framebuffer (the region at
//               full resolution, 0 for a reduced offscreen target), zw = the region's
//               full-resolution size
//   scale       full-resolution pixels per output texel (1, 2, 4)
//   gauss_acc, gauss_near  (PREVIEW_GAUSSIANS 1 only) the sums of rbf_splat_frag.glsl,
//               at full resolution or 1/PREVIEW_GAUSS_SCALE of it (preview_gauss_fetch): rgb = Gaussian airlight sum_i (L_i(Dvp) - L_i(t0)),
//               a = Gaussian optical depth of [t0, Dvp]; near.r = that of [0, t0]. As
//               in the bake: La = e^{T_near} (La_0 + e^{sigma_t t0} rgb) with La_0 the
//               homogeneous airlight from the near point (scaled by C_sv per light),
//               Tr = e^{-sigma_t (Dvp - t0) - a}
//   (and the inputs of preview_common.glsl)

#if PREVIEW_GAUSSIANS
// The Gaussian sums for full-resolution pixel _px_ at distance _Dvp_. At
// PREVIEW_GAUSS_SCALE > 1 the splat targets hold exact samples of the pixels
// q * S + S / 2; blend the four around _px_ with bilinear weights times a depth
// similarity (as preview_upsample_frag.glsl), so Gaussian fog does not leak across
// silhouettes.
void preview_gauss_fetch(ivec2 px, float Dvp, out vec4 g, out float T_near)
{
#if PREVIEW_GAUSS_SCALE <= 1
  g = texelFetch(gauss_acc, px, 0);
  T_near = texelFetch(gauss_near, px, 0).r;
#else
  const int S = PREVIEW_GAUSS_SCALE;
  ivec2 lo_size = textureSize(gauss_acc, 0);
  vec2 f = (vec2(px) - float(S / 2)) / float(S);
  ivec2 q0 = ivec2(floor(f));
  vec2 fw = f - vec2(q0);
  g = vec4(0.0);
  T_near = 0.0;
  float wsum = 0.0;
  for (int k = 0; k < 4; k++) {
    ivec2 o = ivec2(k & 1, k >> 1);
    ivec2 q = clamp(q0 + o, ivec2(0), lo_size - 1);
    ivec2 sp = min(q * S + S / 2, ivec2(viewport.zw) - 1);
    vec2 ndc_k;
    vec3 org_k, dir_k;
    preview_ray(sp, ndc_k, org_k, dir_k);
    float Dk = preview_distance(sp, ndc_k, org_k, dir_k);
    float sim;
    if (isinf(Dk) || isinf(Dvp)) {
      sim = (isinf(Dk) && isinf(Dvp)) ? 1.0 : 0.0;
    }
    else {
      float r = abs(Dk - Dvp) / max(Dvp, 1e-6) / 0.02;
      sim = exp(-r * r);
    }
    vec2 bw = mix(vec2(1.0) - fw, fw, vec2(o));
    float w = bw.x * bw.y * (sim + 1e-6);
    g += w * texelFetch(gauss_acc, q, 0);
    T_near += w * texelFetch(gauss_near, q, 0).r;
    wsum += w;
  }
  g /= wsum;
  T_near /= wsum;
#endif
}
#endif

void main()
{
  ivec2 px = min(ivec2(gl_FragCoord.xy - viewport.xy) * pv_scale + pv_scale / 2,
                 ivec2(viewport.zw) - 1);
  vec2 ndc;
  vec3 origin, dir;
  preview_ray(px, ndc, origin, dir);
  float Dvp = preview_distance(px, ndc, origin, dir);
  vec4 fog = preview_fog(origin, dir, Dvp);
#if PREVIEW_GAUSSIANS
  vec4 g;
  float T_near;
  preview_gauss_fetch(px, Dvp, g, T_near);
  float t0 = min(preview_near(dir), Dvp);
  float T_hom = pv_sigma_t > 0.0 ? pv_sigma_t * max(Dvp - t0, 0.0) : 0.0;  // 0 * inf = NaN
  float Tr = exp(-T_hom - g.a);
  fog = vec4(exp(T_near) * (fog.rgb + exp(pv_sigma_t * t0) * g.rgb), 1.0 - Tr);
#endif
#if PREVIEW_ENV
  preview_env(dir, Dvp, fog);
#endif
#if PREVIEW_LOWRES
  frag_color = vec4(fog.rgb, Dvp);
#else
  frag_color = fog;
#endif
}
