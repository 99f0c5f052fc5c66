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
//   gauss_acc, gauss_near  (PREVIEW_GAUSSIANS 1 only) the full-resolution sums of
//               rbf_splat_frag.glsl: rgb = Gaussian airlight sum_i (L_i(Dvp) - L_i(t0)),
//               a = Gaussian optical depth of [t0, Dvp]; near.r = that of [0, t0]. As
//               in the bake: La = e^{T_near} (La_0 + e^{sigma_t t0} rgb) with La_0 the
//               homogeneous airlight from the near point (scaled by C_sv per light),
//               Tr = e^{-sigma_t (Dvp - t0) - a}
//   (and the inputs of preview_common.glsl)

void main()
{
  ivec2 px = min(ivec2(gl_FragCoord.xy - viewport.xy) * scale + scale / 2,
                 ivec2(viewport.zw) - 1);
  vec2 ndc;
  vec3 origin, dir;
  preview_ray(px, ndc, origin, dir);
  float Dvp = preview_distance(px, ndc, origin, dir);
  vec4 fog = preview_fog(origin, dir, Dvp);
#if PREVIEW_GAUSSIANS
  vec4 g = texelFetch(gauss_acc, px, 0);
  float T_near = texelFetch(gauss_near, px, 0).r;
  float t0 = min(preview_near(dir), Dvp);
  float T_hom = sigma_t > 0.0 ? sigma_t * max(Dvp - t0, 0.0) : 0.0;  // 0 * inf = NaN
  float Tr = exp(-T_hom - g.a);
  fog = vec4(exp(T_near) * (fog.rgb + exp(sigma_t * t0) * g.rgb), 1.0 - Tr);
#endif
#if PREVIEW_LOWRES
  frag_color = vec4(fog.rgb, Dvp);
#else
  frag_color = fog;
#endif
}
