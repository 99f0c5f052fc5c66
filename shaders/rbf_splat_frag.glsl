// rbf_splat_frag.glsl: the contribution of Gaussian _gi_ to one full-resolution pixel,
// added (blend ADDITIVE_PREMULT) into two float targets; fog_preview_frag.glsl with
// PREVIEW_GAUSSIANS combines them with the homogeneous part as the bake does
// (native/kernels/bake.cpp eval_rbf with Fogshop set up at the eye):
//   frag_color.rgb += sum_l I_l (L_il(Dvp) - L_il(t0))   (rbf_gaussian.glsl, eq. 11)
//   frag_color.a   += T_i(t0, Dvp)                         (optical depth of the segment)
//   frag_near.r    += T_i(0, t0)                           (eye to the near plane)
// where [t0, Dvp] is the pixel's clipped view segment (preview_common.glsl). At a
// reduced scale (scale = 2, 4: targets of 1/scale the size) texel q stands for the
// full-resolution pixel q * scale + scale / 2, as in fog_preview_frag.glsl. Gaussians
// whose cull sphere the view segment [0, Dvp] misses are skipped, as the bake's
// RbfMedium::for_each_near does.
//
// Needs sun05_airlight.glsl, preview_common.glsl and rbf_gaussian.glsl in front of it,
// the inputs of preview_common.glsl (lights: row 0 = position, row 1 = albedo I0), and
//   gauss       see rbf_splat_vert.glsl
//   gauss_f1    R32F, RBF_TEX_WIDTH wide: texel (i % W, (i / W) L + l) = f1 of light l
//               and Gaussian i with Gaussian i's own terms removed (rbf_fogshop_light)
//   in: flat int gi

void main()
{
  ivec2 px = min(ivec2(gl_FragCoord.xy) * pv_scale + pv_scale / 2, ivec2(viewport.zw) - 1);
  vec2 ndc;
  vec3 origin, dir;
  preview_ray(px, ndc, origin, dir);
  float Dvp = preview_distance(px, ndc, origin, dir);
  float t0 = min(preview_near(dir), Dvp);

  ivec2 tc = ivec2(gi % RBF_TEX_WIDTH, 2 * (gi / RBF_TEX_WIDTH));
  vec4 ba = texelFetch(gauss, tc, 0);
  vec4 cr = texelFetch(gauss, tc + ivec2(0, 1), 0);
  vec3 b = ba.xyz;
  float a = ba.w, c = cr.x, R = cr.y;
  // Cull like the bake: distance from b to the segment [0, Dvp] below R.
  vec3 rel = b - origin;
  float ts = dot(rel, dir);
  vec3 q = rel - clamp(ts, 0.0, Dvp) * dir;
  if (!(dot(q, q) < R * R)) {
    discard;
  }
  float T_seg = rbf_gaussian_line_integral(c, a, b, origin, dir, t0, Dvp);
  float T_near = rbf_gaussian_line_integral(c, a, b, origin, dir, 0.0, t0);

  vec3 La = vec3(0.0);
  float Tvp, Tvr, Tvp0, Tvr0;
  vec3 xr, xr0;
  bool far_ok = rbf_fogshop_view(b, a, c, origin, dir, Dvp, Tvp, Tvr, xr);
  // L_i(t0) is proportional to T_near: skip it where it cannot matter (a Gaussian
  // away from the eye: T_near is then ~1e-10 of Tvp and the erfs cost as much again).
  bool near_ok = t0 > 0.0 && T_near > 1e-6 * T_seg &&
                 rbf_fogshop_view(b, a, c, origin, dir, t0, Tvp0, Tvr0, xr0);
  if (far_ok) {
    int row = (gi / RBF_TEX_WIDTH) * light_count;
    for (int l = 0; l < light_count; l++) {
      vec3 s = texelFetch(lights, ivec2(l, 0), 0).xyz;
      vec3 I0 = texelFetch(lights, ivec2(l, 1), 0).rgb;
      float f1 = texelFetch(gauss_f1, ivec2(gi % RBF_TEX_WIDTH, row + l), 0).r;
      float L = rbf_fogshop_light(b, a, c, s, f1, Tvp, Tvr, xr);
      if (near_ok) {
        L -= rbf_fogshop_light(b, a, c, s, f1, Tvp0, Tvr0, xr0);
      }
      La += I0 * L;
    }
  }
  frag_color = vec4(La, T_seg);
  frag_near = vec4(T_near, 0.0, 0.0, 0.0);
}
