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
#if PREVIEW_LOWRES
  frag_color = vec4(fog.rgb, Dvp);
#else
  frag_color = fog;
#endif
}
