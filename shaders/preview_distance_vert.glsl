// preview_distance_vert.glsl: an object's triangles (object space, attribute _pos_)
// through _model_ (object to world) and _persp_ (projection * view of the region), for
// the preview's own scene depth. Passes the world position on.
void main()
{
  vec4 world = model * vec4(pos, 1.0);
  wpos = world.xyz / world.w;
  gl_Position = persp * world;
}
