// test_rbf_fast_frag.glsl: rbf_fast_erf_diff (rbf_gaussian.glsl, the bake's fast_erf_diff)
// at one input point per pixel, for tests/gpu/test_preview_gaussians.py.
//   in0 texel = (x1, x2, 0, 0)     out: (rbf_fast_erf_diff(x1, x2), 0, 0, 0)
void main()
{
  vec4 q = texelFetch(in0, ivec2(gl_FragCoord.xy), 0);
  frag_color = vec4(rbf_fast_erf_diff(q.x, q.y), 0.0, 0.0, 0.0);
}
