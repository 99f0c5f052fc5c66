// rbf_tiles_frag.glsl: the Gaussian fog's sums for one pixel of the splat targets in ONE
// full-screen pass (no blending): the pixel's screen tile (RBF_TILE x RBF_TILE target
// texels) lists the Gaussians whose cull-sphere bounds reach it (built on the CPU,
// preview_gaussians.tile_lists), and the pixel loops over them with rbf_splat_pixel.glsl.
// Writes what the quad splat (rbf_splat_frag.glsl) adds up, to the same two targets:
//   frag_color = (sum albedo_i sum_l I0_l (L_il(Dvp) - L_il(t0)), sum T_i(t0, Dvp)),
//   frag_near.r = sum T_i(0, t0).
// Like the bake's tiles (native/gaussian/splat_tile.cpp), but on the GPU every pixel of a
// tile walks the same list, so neighbouring invocations stay in step.
//
//   tile_index  RG32F, one texel per tile: (first entry, count) in tile_list
//   tile_list   R32F, RBF_LIST_WIDTH wide: entry e at (e % W, e / W) = Gaussian index
// (floats hold indices exactly below 2^24.) Needs what rbf_splat_frag.glsl needs.

void main()
{
  rbf_load_lights();
  ivec2 q = ivec2(gl_FragCoord.xy);
  ivec2 px = min(q * pv_scale + pv_scale / 2, ivec2(viewport.zw) - 1);
  vec2 ndc;
  vec3 origin, dir;
  preview_ray(px, ndc, origin, dir);
  float Dvp = preview_distance(px, ndc, origin, dir);
  float t0 = min(preview_near(dir), Dvp);
  vec2 se = texelFetch(tile_index, q / RBF_TILE, 0).xy;
  int first = int(se.x), end = int(se.x) + int(se.y);
  vec3 La = vec3(0.0);
  float T_seg = 0.0, T_near = 0.0;
  for (int e = first; e < end; e++) {
    int gi = int(texelFetch(tile_list, ivec2(e % RBF_LIST_WIDTH, e / RBF_LIST_WIDTH), 0).r);
    rbf_splat_pixel(gi, origin, dir, t0, Dvp, La, T_seg, T_near);
  }
  frag_color = vec4(La, T_seg);
  frag_near = vec4(T_near, 0.0, 0.0, 0.0);
}
