// test_biri_frag.glsl: evaluates biri06_airlight.glsl at one input point per pixel, for
// the GLSL vs C++ agreement test (tests/gpu/test_preview_phase_spot_sun.py).
//   in0 texel = (sigma_t, Dsv, cos_gamma, Dvp); Gtab, phase as in biri06_airlight.glsl
//   out: (biri06_airlight(...), G(lambda = in0.x, T = in0.y) from the table, 0, 1)
void main()
{
  ivec2 p = ivec2(gl_FragCoord.xy);
  vec4 q = texelFetch(in0, p, 0);
  frag_color = vec4(biri06_airlight(Gtab, phase, q.x, q.y, q.z, q.w),
                    biri06_table_G(Gtab, phase, q.x, q.y), 0.0, 1.0);
}
