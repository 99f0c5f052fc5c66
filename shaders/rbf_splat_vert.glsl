// rbf_splat_vert.glsl: one screen-space quad per Gaussian (Fogshop section 5: splat each
// Gaussian over the projected bounds of its cull sphere). The batch holds 4 vertices per
// Gaussian: _corner_ in {-1, 1}^2 and _gid_ the Gaussian's index (float, exact below 2^24),
// so no instancing is needed (Blender 3.4's GPUBatch has no draw_instanced).
//
//   gauss     RGBA32F, RBF_TEX_WIDTH wide, 3 rows per block (rbf_splat_pixel.glsl):
//             texel (i % W, 3 (i / W)) = (b.xyz, a), texel (i % W, 3 (i / W) + 1) =
//             (c, R, ...), R the cull radius sqrt(ln(c sqrt(pi) / (a eps))) / a (0: never
//             reaches a ray by > eps)
//   persp     projection * view of the target
//   eye       xyz = view origin, w = 1 perspective / 0 orthographic
//
// The quad covers the exact screen bounds of the projected cull sphere (tangent planes
// through the eye; for orthographic views the same formula gives centre +- R). Full
// screen when the sphere reaches the eye plane (it holds the eye or crosses it); nothing
// when it lies wholly behind the eye, when R = 0, or when the bounds miss the screen.
//   out: flat int gi (the Gaussian's index)

ivec2 rbf_texel(int i)
{
  return ivec2(i % RBF_TEX_WIDTH, 3 * (i / RBF_TEX_WIDTH));
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
  // Exact NDC bounds of the projected sphere: the planes x_ndc = k through the eye,
  // (r0 - k r3) . (p, 1) = 0 (r0, r3: rows of persp), tangent to the sphere satisfy
  // (a - k b)^2 = R^2 |u - k v|^2 with a = r0 . (c, 1), b = r3 . (c, 1), u = r0.xyz,
  // v = r3.xyz: a quadratic in k whose roots bound x (and likewise y with r1). Valid when
  // the sphere lies in front of the eye plane (b^2 > R^2 |v|^2); else full screen.
  vec4 c1 = vec4(ba.xyz, 1.0);
  vec4 r3 = vec4(persp[0][3], persp[1][3], persp[2][3], persp[3][3]);
  float bw = dot(r3, c1), R2 = R * R;
  float A = bw * bw - R2 * dot(r3.xyz, r3.xyz);
  vec2 lo = vec2(-1.0), hi = vec2(1.0);
  if (A > 1e-12 * bw * bw && bw > 0.0) {
    for (int axis = 0; axis < 2; axis++) {
      vec4 r = vec4(persp[0][axis], persp[1][axis], persp[2][axis], persp[3][axis]);
      float a = dot(r, c1);
      float Bh = a * bw - R2 * dot(r.xyz, r3.xyz);  // half of -B
      float C = a * a - R2 * dot(r.xyz, r.xyz);
      float disc = max(Bh * Bh - A * C, 0.0);
      float k0 = (Bh - sqrt(disc)) / A, k1 = (Bh + sqrt(disc)) / A;
      lo[axis] = k0;
      hi[axis] = k1;
    }
  }
  else if (bw < 0.0 && A > 0.0) {
    gl_Position = vec4(2.0, 2.0, 2.0, 1.0);  // wholly behind the eye
    return;
  }
  lo = max(lo, vec2(-1.0));
  hi = min(hi, vec2(1.0));
  if (any(greaterThanEqual(lo, hi))) {
    gl_Position = vec4(2.0, 2.0, 2.0, 1.0);
    return;
  }
  gl_Position = vec4(mix(lo, hi, corner * 0.5 + 0.5), 0.0, 1.0);
}
