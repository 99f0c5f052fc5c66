// depth_only_vert.glsl: world-space triangles through _persp_ (projection * view), for
// rendering scene depth (tests, benchmarks).
void main()
{
  gl_Position = persp * vec4(pos, 1.0);
}
