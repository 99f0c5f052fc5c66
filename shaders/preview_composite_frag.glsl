// preview_composite_frag.glsl: copies the full-resolution upsampled fog (premultiplied:
// rgb = airlight, a = 1 - Tr; preview_upsample_frag.glsl) onto the region, texel for
// pixel; with ALPHA_PREMULT blending that is L = La + Tr L_scene.
//   fog_lo      the full-resolution fog target (this pass's only input)
//   viewport    xy = lower-left corner of the region in the framebuffer
void main()
{
  frag_color = texelFetch(fog_lo, ivec2(gl_FragCoord.xy - viewport.xy), 0);
}
