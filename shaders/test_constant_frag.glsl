// test_constant_frag.glsl: smoke test, writes the push constant _color_ everywhere.
void main()
{
  frag_color = color;
}
