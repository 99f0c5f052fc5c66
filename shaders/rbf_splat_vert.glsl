// rbf_splat_vert.glsl: one screen-space quad per Gaussian (Fogshop section 5: splat each
// Gaussian over the projected bounds of its cull sphere). The batch holds 4 vertices per
// Gaussian: _corner_ in {-1, 1}^2 and _gid_ the Gaussian's index (float, exact below 2^24),
// so no instancing is needed (Blender 3.4's GPUBatch has no draw_instanced).
//
//   gauss     RGBA32F, RBF_TEX_WIDTH wide: texel (i % W, 2 (i / W)) = (b.xyz, a),
//             texel (i % W, 2 (i / W) + 1) = (c, R, 0, 0), R the cull radius
//             sqrt(ln(c sqrt(pi) / (a eps))) / a (0: never reaches a ray by > eps)
//   persp     projection * view of the target
//   eye       xyz = view origin, w = 1 perspective / 0 orthographic
//
// The quad covers the projection of the sphere's bounding box (its 8 corners; exact
// for a convex set in front of the eye). Full screen when a corner is on or behind the
// eye plane (the sphere holds the eye or crosses it). Degenerate (nothing drawn) when
// R = 0 or the bounds miss the screen.
//   out: flat int gi (the Gaussian's index)

ivec2 rbf_texel(int i)
{
  return ivec2(i % RBF_TEX_WIDTH, 2 * (i / RBF_TEX_WIDTH));
}

void main()
{
  int i = int(gid + 0.5);
  gi = i;
  ivec2 tc = rbf_texel(i);
  vec4 ba = texelFetch(gauss, tc, 0);
  float R = texelFetch(gauss, tc + ivec2(0, 1), 0).y;
  if (!(R > 0.0)) {
    gl_Position = vec4(2.0, 2.0, 2.0, 1.0);  // outside the clip volume: culled
    return;
  }
  vec2 lo = vec2(1e30), hi = vec2(-1e30);
  bool full = false;
  for (int k = 0; k < 8; k++) {
    vec3 sgn = vec3((k & 1) != 0 ? 1.0 : -1.0, (k & 2) != 0 ? 1.0 : -1.0, (k & 4) != 0 ? 1.0 : -1.0);
    vec4 q = persp * vec4(ba.xyz + R * sgn, 1.0);
    if (!(q.w > 1e-6)) {
      full = true;
      break;
    }
    vec2 ndc = q.xy / q.w;
    lo = min(lo, ndc);
    hi = max(hi, ndc);
  }
  if (full) {
    lo = vec2(-1.0);
    hi = vec2(1.0);
  }
  lo = max(lo, vec2(-1.0));
  hi = min(hi, vec2(1.0));
  if (any(greaterThanEqual(lo, hi))) {
    gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
    return;
  }
  gl_Position = vec4(mix(lo, hi, corner * 0.5 + 0.5), 0.0, 1.0);
}
