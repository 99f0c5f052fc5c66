// bench_gaussian_splat_vert.glsl (harness-local stand-in, see ../README.md): one
// instanced quad per Gaussian (gl_InstanceID), covering the screen bounds of its cull
// sphere (centre b_i, radius R_i = sqrt(ln(c_i sqrt(pi) / (a_i eps))) / a_i, medium.h);
// the whole screen when the sphere holds the eye or reaches the near plane.
//   in:  vec2 pos (quad corner, 0..1)
//   out: flat int gid (the Gaussian)
//   gauss   RGBA32F, N x 2 texels: row 0 = (b_i, a_i), row 1 = (c_i, R_i, 0, 0)
//   persp   projection * view of the region; eye, clip as in preview_common.glsl
void main()
{
  gid = gl_InstanceID;
  vec4 ba = texelFetch(gauss, ivec2(gid, 0), 0);
  float R = texelFetch(gauss, ivec2(gid, 1), 0).y;
  vec3 b = ba.xyz;
  vec2 lo = vec2(-1.0), hi = vec2(1.0);
  // Near-plane depth of the sphere's nearest point along the view axis.
  float depth_near = dot(b - eye.xyz, clip.xyz) - R;
  if (R <= 0.0) {
    lo = hi = vec2(2.0);  // nothing to draw: a degenerate quad off screen
  }
  else if (depth_near > clip.w) {
    // Bounds of the 8 corners of the sphere's bounding cube (conservative).
    lo = vec2(1e30);
    hi = vec2(-1e30);
    for (int k = 0; k < 8; k++) {
      vec3 corner = b + R * vec3((k & 1) != 0 ? 1.0 : -1.0, (k & 2) != 0 ? 1.0 : -1.0,
                                 (k & 4) != 0 ? 1.0 : -1.0);
      vec4 p = persp * vec4(corner, 1.0);
      vec2 ndc = p.xy / p.w;
      lo = min(lo, ndc);
      hi = max(hi, ndc);
    }
    lo = clamp(lo, vec2(-1.0), vec2(1.0));
    hi = clamp(hi, vec2(-1.0), vec2(1.0));
  }
  gl_Position = vec4(mix(lo, hi, pos), 0.0, 1.0);
}
