// bench_gaussian_composite_frag.glsl (harness-local stand-in): puts the accumulated
// Gaussian fog (rgb = airlight, a = optical depth, at 1/scale resolution: the texel whose
// sample pixel is nearest) over the region with ALPHA_PREMULT blending:
// L = La_g + exp(-T_g) L_behind.
void main()
{
  ivec2 px = ivec2(gl_FragCoord.xy - viewport.xy);
  ivec2 q = min(px / scale, textureSize(fog_lo, 0) - 1);
  vec4 g = texelFetch(fog_lo, q, 0);
  frag_color = vec4(g.rgb, 1.0 - exp(-g.a));
}
