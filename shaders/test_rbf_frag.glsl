// test_rbf_frag.glsl: evaluates rbf_gaussian.glsl at one input point per pixel, for the
// GLSL vs C++ agreement test (tests/gpu/test_preview_gaussians.py).
//   in0 texel = (x1, x2, D, f1)      in1 texel = (b.xyz, a)
//   in2 texel = (o.xyz, c)           in3 texel = (r.xyz unit, 0)    in4 texel = (s.xyz, 0)
//   out: (rbf_erf_diff(x1, x2), rbf_erf(x1), T_i(o, o + D r), L_i(b, a, c, o, r, D, s, f1))
void main()
{
  ivec2 p = ivec2(gl_FragCoord.xy);
  vec4 q0 = texelFetch(in0, p, 0);
  vec4 q1 = texelFetch(in1, p, 0);
  vec4 q2 = texelFetch(in2, p, 0);
  vec3 r = texelFetch(in3, p, 0).xyz;
  vec3 s = texelFetch(in4, p, 0).xyz;
  frag_color = vec4(rbf_erf_diff(q0.x, q0.y), rbf_erf(q0.x),
                    rbf_gaussian_line_integral(q2.w, q1.w, q1.xyz, q2.xyz, r, 0.0, q0.z),
                    rbf_fogshop_Li(q1.xyz, q1.w, q2.w, q2.xyz, r, q0.z, s, q0.w));
}
