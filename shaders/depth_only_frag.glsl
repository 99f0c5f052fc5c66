// depth_only_frag.glsl: depth is all we need; the colour is a constant.
void main()
{
  frag_color = vec4(1.0);
}
