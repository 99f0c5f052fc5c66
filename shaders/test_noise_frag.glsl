// test_noise_frag.glsl: rbf_gradient_noise3 (rbf_noise.glsl) at one input point per
// pixel, for the GLSL vs C++ agreement test (tests/gpu/test_preview_noise.py).
//   in0 texel = (p.xyz, 0)     out: (noise3(p), 0)
void main()
{
  vec3 p = texelFetch(in0, ivec2(gl_FragCoord.xy), 0).xyz;
  frag_color = vec4(rbf_gradient_noise3(p), 0.0);
}
