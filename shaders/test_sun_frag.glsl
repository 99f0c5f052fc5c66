// test_sun_frag.glsl: sun_layer_factor (sun_airlight.glsl) at one input point per pixel.
//   in0 texel = (sigma_t, h_top, mu_s, o_z)   in1 texel = (d_z, t0, t1, 0)
//   out: (sun_layer_factor(...), 0, 0, 1)
void main()
{
  ivec2 p = ivec2(gl_FragCoord.xy);
  vec4 a = texelFetch(in0, p, 0);
  vec4 b = texelFetch(in1, p, 0);
  frag_color = vec4(sun_layer_factor(a.x, a.y, a.z, a.w, b.x, b.y, b.z), 0.0, 0.0, 1.0);
}
