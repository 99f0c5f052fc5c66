// fullscreen_vert.glsl: a full-screen quad in clip space. _uv_ runs from 0 at the
// bottom-left corner to 1 at the top-right corner of the target.
//   in:  vec2 pos (clip-space corner, -1..1)
//   out: vec2 uv
void main()
{
  uv = pos * 0.5 + 0.5;
  gl_Position = vec4(pos, 0.0, 1.0);
}
