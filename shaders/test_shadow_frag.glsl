// test_shadow_frag.glsl: shadow_lit (shadow_maps.glsl) at one input point per pixel.
//   in0 texel = (world point, shadow-map row)
//   out: (shadow_lit(row, point), 0, 0, 1)
void main()
{
  vec4 a = texelFetch(in0, ivec2(gl_FragCoord.xy), 0);
  frag_color = vec4(shadow_lit(int(a.w), a.xyz), 0.0, 0.0, 1.0);
}
