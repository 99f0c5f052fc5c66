// rbf_splat_frag.glsl: the contribution of Gaussian _gi_ to one pixel of the splat
// targets (rbf_splat_pixel.glsl), added (blend ADDITIVE_PREMULT) into two float targets;
// fog_preview_frag.glsl with PREVIEW_GAUSSIANS combines them with the homogeneous part as
// the bake does (native/bake/fog_evaluator.cpp FogEvaluator::eval_gaussians, Fogshop set up
// at the eye):
//   frag_color.rgb += albedo_i sum_l I0_l (L_il(Dvp) - L_il(t0))
//   frag_color.a   += T_i(t0, Dvp)
//   frag_near.r    += T_i(0, t0)
// where [t0, Dvp] is the pixel's clipped view segment (preview_common.glsl). At a
// reduced scale (scale = 2, 4: targets of 1/scale the size) texel q stands for the
// full-resolution pixel q * scale + scale / 2, as in fog_preview_frag.glsl.
//
// Needs sun05_airlight.glsl, preview_common.glsl, rbf_gaussian.glsl, rbf_noise.glsl and
// rbf_splat_pixel.glsl (its inputs) in front of it.
//   in: flat int gi

void main()
{
  rbf_load_lights();
  ivec2 px = min(ivec2(gl_FragCoord.xy) * pv_scale + pv_scale / 2, ivec2(viewport.zw) - 1);
  vec2 ndc;
  vec3 origin, dir;
  preview_ray(px, ndc, origin, dir);
  float Dvp = preview_distance(px, ndc, origin, dir);
  float t0 = min(preview_near(dir), Dvp);
  vec3 La = vec3(0.0);
  float T_seg = 0.0, T_near = 0.0;
  rbf_splat_pixel(gi, origin, dir, t0, Dvp, La, T_seg, T_near);
  if (T_seg == 0.0 && T_near == 0.0) {
    discard;  // culled: nothing to add
  }
  frag_color = vec4(La, T_seg);
  frag_near = vec4(T_near, 0.0, 0.0, 0.0);
}
