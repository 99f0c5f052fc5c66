// test_airlight_frag.glsl: evaluates the shared GLSL physics (sun05_airlight.glsl) at
// one input point per pixel, for the GLSL vs C++ agreement test.
//   airlight_inputs texel = (sigma_t, Dsv, cos_gamma, Dvp)
//   f_inputs texel        = (u, T = tan v, 0, 0)
//   out: (sun05_airlight(...), airlight_F(u, T), 0, 1)
void main()
{
  ivec2 p = ivec2(gl_FragCoord.xy);
  vec4 q = texelFetch(airlight_inputs, p, 0);
  vec4 f = texelFetch(f_inputs, p, 0);
  frag_color = vec4(sun05_airlight(Ftab, q.x, q.y, q.z, q.w),
                    airlight_F(Ftab, f.x, f.y), 0.0, 1.0);
}
